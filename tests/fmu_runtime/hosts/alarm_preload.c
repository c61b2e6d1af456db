/* A library that, preloaded into a host (LD_PRELOAD), makes its process take SIGALRM every
 * 10 ms from its start, caught by a handler installed without SA_RESTART, as CPython
 * installs its own: a blocking call the signal lands in (waitpid, poll, read) then fails
 * with EINTR, which the runtime has to take as "again", not as an answer.
 */
#define _GNU_SOURCE
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/time.h>

static volatile sig_atomic_t alarms;

static void count(int signal_number)
{
    (void)signal_number;
    alarms++;
}

__attribute__((constructor)) static void start_alarms(void)
{
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = count;
    sigemptyset(&action.sa_mask);
    action.sa_flags = 0; /* no SA_RESTART */
    struct itimerval every = {{0, 10000}, {0, 10000}};
    if (sigaction(SIGALRM, &action, NULL) || setitimer(ITIMER_REAL, &every, NULL)) {
        perror("alarm_preload");
    }
}
