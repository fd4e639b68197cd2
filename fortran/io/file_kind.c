/* The type of a file, which Fortran cannot ask: for pymr_io_text_file's not_regular. */
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
