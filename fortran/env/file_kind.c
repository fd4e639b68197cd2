/* What Fortran cannot ask about files, or do with them: for pymr_env_text_file's not_regular,
   not_replaceable, same_file, unwritable_folder, longest_name and write_standard_output. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* 0: no such file, 1: a regular file, 2: a directory, 3: anything else (a FIFO, a socket,
   a device), 4: a loop of symbolic links, 5: a symbolic link to nothing, 6: a folder on the
   way that may not be searched. Symbolic links are followed. */
int pymr_file_kind(const char *path)
{
    struct stat s;
    if (stat(path, &s) != 0) {
        if (errno == ELOOP) return 4;
        if (errno == EACCES) return 6;
        if (lstat(path, &s) == 0 && S_ISLNK(s.st_mode)) return 5;
        return 0;
    }
    if (S_ISREG(s.st_mode)) return 1;
    if (S_ISDIR(s.st_mode)) return 2;
    return 3;
}

/* 1: path itself is a symbolic link (not followed), 0: anything else or nothing. */
int pymr_is_link(const char *path)
{
    struct stat s;
    return lstat(path, &s) == 0 && S_ISLNK(s.st_mode);
}

/* 1: a and b are one file on the disk (the same device and inode; links followed), 0: two
   files, -1: either cannot be seen (the caller compares the paths). */
int pymr_same_file(const char *a, const char *b)
{
    struct stat sa, sb;
    if (stat(a, &sa) != 0 || stat(b, &sb) != 0) return -1;
    return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

/* Write n bytes of buf to the standard output (file descriptor 1), all of them (a write
   interrupted or cut short goes on). 0 when done; else -1 with the reason in why (at most
   whylen - 1 bytes, NUL-ended): gfortran's preconnected unit reports no failed write or
   flush, so a summary sent to a full disk or a closed output was lost with exit 0. */
int pymr_write_stdout(const char *buf, size_t n, char *why, size_t whylen)
{
    size_t done = 0;
    while (done < n) {
        ssize_t k = write(1, buf + done, n - done);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) {
            strncpy(why, k < 0 ? strerror(errno) : "nothing written", whylen - 1);
            why[whylen - 1] = '\0';
            return -1;
        }
        done += (size_t)k;
    }
    return 0;
}

/* 0 when the process may make files in the folder `dir` (write and search permission, a
   file system mounted for writing and one that takes new files); else -1 with the system's
   reason in why (at most whylen - 1 bytes, NUL-ended). Root passes access() where the file
   system still refuses a new file (/sys): a file of a unique name is made there and removed,
   as the results' lock file is made before the run (a checkpoint_file in /sys failed only
   at the first checkpoint, exit 2). */
int pymr_unwritable_folder(const char *dir, char *why, size_t whylen)
{
    char probe[4352];
    int fd;
    if (access(dir, W_OK | X_OK) == 0) {
        if (snprintf(probe, sizeof probe, "%s/.pymr-probe-XXXXXX", dir) >= (int)sizeof probe) return 0;
        fd = mkstemp(probe);
        if (fd >= 0) {
            close(fd);
            unlink(probe);
            return 0;
        }
    }
    strncpy(why, strerror(errno), whylen - 1);
    why[whylen - 1] = '\0';
    return -1;
}

/* The longest file name (one path component, in bytes) the file system of the folder `dir`
   takes; 255 (Linux's NAME_MAX) when it does not say. */
long pymr_longest_name(const char *dir)
{
    long n = pathconf(dir, _PC_NAME_MAX);
    return n > 0 ? n : 255;
}
