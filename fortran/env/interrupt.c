/* SIGINT and SIGTERM during a run: caught as a flag the run polls after each step, so that
   it stops as a failed run does (its partial results kept, its lock released, one line),
   for pymr_env_interrupt. The dispositions before the run are restored after it (inside
   Python, its own Ctrl-C), and a signal the caller ignores (a background job's SIGINT)
   stays ignored. */
#include <signal.h>
#include <string.h>

static volatile sig_atomic_t caught = 0;
static struct sigaction before[2];
static int held[2] = {0, 0};
static const int watched[2] = {SIGINT, SIGTERM};

static void on_signal(int sig) { caught = sig; }

void pymr_catch_interrupts(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    caught = 0;
    for (int i = 0; i < 2; i++) {
        if (held[i] || sigaction(watched[i], NULL, &before[i]) != 0) continue;
        if (before[i].sa_handler == SIG_IGN) continue;
        held[i] = sigaction(watched[i], &sa, NULL) == 0;
    }
}

void pymr_release_interrupts(void)
{
    for (int i = 0; i < 2; i++) {
        if (held[i]) sigaction(watched[i], &before[i], NULL);
        held[i] = 0;
    }
}

/* The signal caught since pymr_catch_interrupts (0: none). */
int pymr_interrupt_caught(void) { return (int)caught; }
