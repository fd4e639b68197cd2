/* The lock a run holds on its results (OUT.lock), for pymr_env_text_file: an advisory
   flock(2) on the lock file, which the system releases when the process ends however it
   ends. A lock left by a killed run is then free to take, two runs can never both take one
   (they could when each removed a dead run's lock and made its own: both wrote one partial
   file and a mix of the two was renamed into place), and a process id reused by another
   program does not hold it. The file holds the holder's process id, for the message. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAX_HELD 64
static struct { int fd; char *path; } held[MAX_HELD];

static int same_file(int fd, const char *path)
{
    struct stat a, b;
    return fstat(fd, &a) == 0 && stat(path, &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}

/* The process id written in an open lock file (0 when none is written yet: it is written
   just after the lock is taken, so wait for it a little). */
static int holder_of(int fd)
{
    char buf[32];
    for (int k = 0; k < 40; k++) {
        ssize_t n = pread(fd, buf, sizeof buf - 1, 0);
        if (n > 0) {
            buf[n] = '\0';
            if (atoi(buf) > 0) return atoi(buf);
        }
        usleep(5000);
    }
    return 0;
}

/* Take the lock file `path`: 0 taken; 1 another living process holds it (*holder its id,
   0 if unknown); 2 it cannot be made or written (`reason`, the system's words). */
int pymr_lock_take(const char *path, int *holder, char *reason, int nreason)
{
    int slot = -1;
    *holder = 0;
    reason[0] = '\0';
    for (int i = 0; i < MAX_HELD; i++)
        if (held[i].path == NULL) { slot = i; break; }
    for (int attempt = 0; attempt < 100 && slot >= 0; attempt++) {
        int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (fd < 0) break;
        if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            int e = errno;
            if (e == EWOULDBLOCK) {
                *holder = holder_of(fd);
                close(fd);
                return 1;
            }
            /* a file system without flock (Lustre mounted without it): the run goes on
               with the file written, as the lock it can have */
            if (e != ENOSYS && e != EINVAL && e != EOPNOTSUPP && e != ENOLCK) {
                close(fd);
                errno = e;
                break;
            }
        }
        if (!same_file(fd, path)) {     /* removed by its last holder after we opened it */
            close(fd);
            continue;
        }
        char buf[32];
        int n = snprintf(buf, sizeof buf, "%d\n", (int)getpid());
        if (ftruncate(fd, 0) != 0 || pwrite(fd, buf, n, 0) != n) {
            int e = errno;
            unlink(path);
            close(fd);
            errno = e;
            break;
        }
        held[slot].fd = fd;
        held[slot].path = strdup(path);
        return 0;
    }
    snprintf(reason, nreason, "%s", slot < 0 ? "too many locks held" : strerror(errno));
    return 2;
}

/* Release the lock on `path` this process holds (removing the file), if it holds it. */
void pymr_lock_release(const char *path)
{
    for (int i = 0; i < MAX_HELD; i++) {
        if (held[i].path == NULL || strcmp(held[i].path, path) != 0) continue;
        if (same_file(held[i].fd, path)) unlink(path);
        close(held[i].fd);
        free(held[i].path);
        held[i].path = NULL;
        return;
    }
}
