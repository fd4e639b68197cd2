/* What Fortran cannot ask about the system's memory: for pymr_env_memory. */
#include <stdio.h>
#include <sys/resource.h>
#include <unistd.h>

/* The process's address space now (bytes; 0 where /proc does not say). */
static double address_space(void)
{
    unsigned long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f == NULL) return 0.0;
    if (fscanf(f, "%lu", &pages) != 1) pages = 0;
    fclose(f);
    return (double)pages * (double)sysconf(_SC_PAGE_SIZE);
}

/* The bytes a process may still take: the machine's physical memory, or less where an
   address-space limit (ulimit -v, less what the process holds) or a data limit (ulimit -d)
   is set; -1 when none is known. */
double pymr_memory_limit(void)
{
    int known = 0;
    double bytes = 0.0, lim;
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGE_SIZE);
    struct rlimit r;
    if (pages > 0 && size > 0) {
        bytes = (double)pages * (double)size;
        known = 1;
    }
    if (getrlimit(RLIMIT_AS, &r) == 0 && r.rlim_cur != RLIM_INFINITY) {
        lim = (double)r.rlim_cur - address_space();
        if (!known || lim < bytes) bytes = lim;
        known = 1;
    }
    if (getrlimit(RLIMIT_DATA, &r) == 0 && r.rlim_cur != RLIM_INFINITY) {
        lim = (double)r.rlim_cur;
        if (!known || lim < bytes) bytes = lim;
        known = 1;
    }
    if (!known) return -1.0;
    return bytes > 0.0 ? bytes : 0.0;
}
