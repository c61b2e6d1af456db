/* Ask a candidate Python, in a subprocess, for its version, libpython, prefixes, search path
 * and whether it imports numpy (and has numba).
 *
 * Written by hand because it runs inside an arbitrary FMI host: no shell (a path may hold
 * any character), no popen (its stderr would reach the host's terminal), and a deadline.
 * The script is valid Python 2 and 3, so that an old `python` on PATH still says which
 * version it is; paths travel hex-encoded (any byte, any newline).
 */
#define _GNU_SOURCE
#include "probe.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

static const char SCRIPT[] =
    "import sys\n"
    "def w(key, value):\n"
    "    sys.stdout.write(key + '=' + value + '\\n')\n"
    "def h(text):\n"
    "    import binascii\n"
    "    if not isinstance(text, bytes):\n"
    "        text = text.encode(sys.getfilesystemencoding(), 'surrogateescape')\n"
    "    return binascii.hexlify(text).decode('ascii')\n"
    "w('version', '%d.%d.%d' % tuple(sys.version_info[:3]))\n"
    "sys.stdout.flush()\n"
    "import os, platform, sysconfig\n"
    "w('implementation', platform.python_implementation())\n"
    "v = sysconfig.get_config_var\n"
    "found = ''\n"
    "for d in (v('LIBDIR'), os.path.join(v('LIBDIR') or '', v('MULTIARCH') or ''), v('LIBPL')):\n"
    "    for n in (v('INSTSONAME'), v('LDLIBRARY')):\n"
    "        if not found and d and n and '.so' in n and os.path.isfile(os.path.join(d, n)):\n"
    "            found = os.path.join(d, n)\n"
    "w('libpython', h(found))\n"
    "w('base_prefix', h(getattr(sys, 'base_prefix', sys.prefix)))\n"
    "w('stdlib', h(sysconfig.get_path('stdlib')))\n"
    "w('executable', h(sys.executable))\n"
    "w('path', ':'.join(h(p) for p in sys.path if p))\n"
    "try:\n"
    "    import numpy\n"
    "    w('numpy', numpy.__version__)\n"
    "except Exception as e:\n"
    "    w('numpy_error', h('%s: %s' % (type(e).__name__, e)))\n"
    "try:\n"
    "    import importlib.util\n"
    "    w('numba', importlib.util.find_spec('numba') and 'yes' or 'no')\n"
    "except Exception:\n"
    "    w('numba', 'no')\n"
    "w('end', 'yes')\n";

#define OUT_LIMIT (1 << 20)
#define ERR_LIMIT (1 << 14)

typedef struct {
    char *data;
    size_t size, limit;
} Buffer;

/* The host's environment without PYTHONHOME (a pointer array; the strings are shared). */
static char **child_environment(void)
{
    size_t n = 0;
    while (environ && environ[n]) n++;
    char **copy = calloc(n + 1, sizeof *copy);
    if (!copy) return NULL;
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        if (strncmp(environ[i], "PYTHONHOME=", 11)) copy[j++] = environ[i];
    }
    return copy;
}

static void append(Buffer *b, const char *data, size_t n)
{
    if (b->size + n > b->limit) n = b->limit - b->size;
    memcpy(b->data + b->size, data, n);
    b->size += n;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Read both pipes to their end or the deadline; 1 if both ended. */
static int drain(int out, int err, Buffer *stdout_text, Buffer *stderr_text)
{
    struct pollfd fds[2] = {{out, POLLIN, 0}, {err, POLLIN, 0}};
    Buffer *into[2] = {stdout_text, stderr_text};
    double deadline = now() + PROBE_TIMEOUT_S;
    char chunk[4096];
    while (fds[0].fd >= 0 || fds[1].fd >= 0) {
        int left = (int)((deadline - now()) * 1000.0);
        if (left <= 0) return 0;
        int ready = poll(fds, 2, left);
        if (ready < 0 && errno == EINTR) continue;
        if (ready <= 0) return 0;
        for (int i = 0; i < 2; i++) {
            if (fds[i].fd < 0 || !fds[i].revents) continue;
            ssize_t got = read(fds[i].fd, chunk, sizeof chunk);
            if (got > 0) {
                append(into[i], chunk, (size_t)got);
            } else if (got == 0 || errno != EINTR) {
                fds[i].fd = -1;
            }
        }
    }
    return 1;
}

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
}

/* Decode ``n`` hex digits of ``hex`` into ``out`` (NUL-terminated, truncated to size). */
static void unhex(const char *hex, size_t n, char *out, size_t size)
{
    size_t j = 0;
    for (size_t i = 0; i + 1 < n && j + 1 < size; i += 2) {
        int high = hex_value(hex[i]), low = hex_value(hex[i + 1]);
        if (high < 0 || low < 0) break;
        out[j++] = (char)(high * 16 + low);
    }
    out[j] = '\0';
}

/* "hex:hex:..." as entries each followed by '\0'. */
static void unhex_path(const char *text, Answer *a)
{
    size_t length = strlen(text);
    a->path = calloc(length + 2, 1); /* each entry's bytes and NUL fit in its hex digits */
    if (!a->path) return;
    char *out = a->path;
    while (*text) {
        size_t n = strcspn(text, ":");
        unhex(text, n, out, n / 2 + 1);
        out += strlen(out) + 1;
        a->paths++;
        text += n + (text[n] == ':');
    }
}

static void parse(char *text, Answer *a)
{
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        char *value = strchr(line, '=');
        if (!value) continue;
        *value++ = '\0';
        size_t n = strlen(value);
        if (!strcmp(line, "version")) {
            sscanf(value, "%d.%d.%d", &a->major, &a->minor, &a->micro);
        } else if (!strcmp(line, "implementation")) {
            snprintf(a->implementation, sizeof a->implementation, "%s", value);
        } else if (!strcmp(line, "libpython")) {
            unhex(value, n, a->libpython, sizeof a->libpython);
        } else if (!strcmp(line, "base_prefix")) {
            unhex(value, n, a->base_prefix, sizeof a->base_prefix);
        } else if (!strcmp(line, "stdlib")) {
            unhex(value, n, a->stdlib, sizeof a->stdlib);
        } else if (!strcmp(line, "executable")) {
            unhex(value, n, a->executable, sizeof a->executable);
        } else if (!strcmp(line, "path") && !a->path) {
            unhex_path(value, a);
        } else if (!strcmp(line, "numpy")) {
            snprintf(a->numpy, sizeof a->numpy, "%s", value);
        } else if (!strcmp(line, "numpy_error")) {
            unhex(value, n, a->numpy_error, sizeof a->numpy_error);
        } else if (!strcmp(line, "numba")) {
            a->numba = !strcmp(value, "yes");
        } else if (!strcmp(line, "end")) {
            a->answered = 1;
        }
    }
}

/* The last non-empty line of the child's stderr, or "". */
static const char *last_line(Buffer *b)
{
    while (b->size && (b->data[b->size - 1] == '\n' || b->data[b->size - 1] == '\r')) b->size--;
    b->data[b->size] = '\0';
    char *line = strrchr(b->data, '\n');
    return line ? line + 1 : b->data;
}

/* Why a child that did not answer failed, from its wait status. */
static void explain(Answer *a, int finished, int waited, int status, Buffer *err)
{
    const char *said = last_line(err);
    const char *sep = said[0] ? ": " : "";
    if (!finished) {
        snprintf(a->failure, sizeof a->failure, "gave no answer within %d s", PROBE_TIMEOUT_S);
    } else if (waited && WIFSIGNALED(status)) {
        snprintf(a->failure, sizeof a->failure, "was killed by signal %d%s%s", WTERMSIG(status),
                 sep, said);
    } else if (waited && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
        snprintf(a->failure, sizeof a->failure, "gave no answer the runtime understands%s%s",
                 sep, said);
    } else if (waited && WIFEXITED(status)) {
        snprintf(a->failure, sizeof a->failure, "exited with status %d before answering%s%s",
                 WEXITSTATUS(status), sep, said);
    } else {
        snprintf(a->failure, sizeof a->failure, "did not answer%s%s", sep, said);
    }
}

static int spawn(const char *executable, int out[2], int err[2], pid_t *pid)
{
    char *argv[] = {(char *)executable, (char *)"-c", (char *)SCRIPT, NULL};
    char **env = child_environment();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, out[1], 1);
    posix_spawn_file_actions_adddup2(&actions, err[1], 2);
    int failed = env ? posix_spawn(pid, executable, &actions, NULL, argv, env) : ENOMEM;
    posix_spawn_file_actions_destroy(&actions);
    free(env);
    return failed;
}

void probe(const char *executable, Answer *a)
{
    memset(a, 0, sizeof *a);
    int out[2] = {-1, -1}, err[2] = {-1, -1};
    Buffer text = {malloc(OUT_LIMIT + 1), 0, OUT_LIMIT};
    Buffer errors = {malloc(ERR_LIMIT + 1), 0, ERR_LIMIT};
    pid_t pid = 0;
    int failed = !text.data || !errors.data ? ENOMEM
                 : pipe2(out, O_CLOEXEC) || pipe2(err, O_CLOEXEC) ? errno
                                                                  : spawn(executable, out, err, &pid);
    if (out[1] >= 0) close(out[1]);
    if (err[1] >= 0) close(err[1]);
    if (failed) {
        snprintf(a->failure, sizeof a->failure, "could not be run (%s)", strerror(failed));
    } else {
        int finished = drain(out[0], err[0], &text, &errors);
        if (!finished) kill(pid, SIGKILL);
        int status = 0;
        int waited = waitpid(pid, &status, 0) == pid; /* not when the host ignores SIGCHLD */
        text.data[text.size] = '\0';
        parse(text.data, a);
        if (!a->answered) explain(a, finished, waited, status, &errors);
    }
    if (out[0] >= 0) close(out[0]);
    if (err[0] >= 0) close(err[0]);
    free(text.data);
    free(errors.data);
}
