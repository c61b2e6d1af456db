/* Ask one candidate Python what it is, in a subprocess of its own. */
#ifndef AUV_FMU_PROBE_H
#define AUV_FMU_PROBE_H

#include "loader.h"

#define PROBE_TIMEOUT_S 60

typedef struct {
    int answered;       /* it printed its whole answer */
    char failure[1024]; /* why not: could not run, exit status, its stderr's "Fatal Python
                         * error: " line or else its last line, a standard library on
                         * PYTHONPATH */
    int major, minor, micro;
    char bad_version[48]; /* its version as it said it, when not three numbers (else "") */
    char implementation[32]; /* platform.python_implementation(): CPython, PyPy, ... */
    char libpython[PATH_SIZE]; /* its shared libpython, "" if it has none */
    char base_prefix[PATH_SIZE];
    char stdlib[PATH_SIZE];
    char executable[PATH_SIZE];
    char too_long[16]; /* the first of those it named with a path too long for them */
    char *path;   /* its sys.path, each entry followed by a '\0' (malloc'd) */
    size_t paths; /* how many entries */
    char numpy[64];        /* numpy.__version__, "" if it cannot import numpy */
    char numpy_error[512]; /* why it cannot */
    int numba;             /* 1 if numba is installed */
} Answer;

/* Run ``executable [argument] -c <probe>`` once (platform_run: no shell, stdin empty,
 * stdout and stderr captured: nothing reaches the host's terminal; PYTHONHOME and
 * PYTHONUTF8 left out of its environment, since the runtime sets the home and UTF-8 mode
 * itself) and fill ``answer``.
 * ``argument`` is NULL, or "-3" for Windows' py launcher. */
void probe(const char *executable, const char *argument, Answer *answer);

#endif
