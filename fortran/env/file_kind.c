/* What Fortran cannot ask about files: for pymr_env_text_file's not_regular, not_replaceable and
   same_file. */
#include <sys/stat.h>

/* 0: no such file (or it cannot be seen), 1: a regular file, 2: a directory, 3: anything
   else (a FIFO, a socket, a device). Symbolic links are followed. */
int pymr_file_kind(const char *path)
{
    struct stat s;
    if (stat(path, &s) != 0) return 0;
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
