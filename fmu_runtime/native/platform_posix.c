/* platform.h on linux64: dlopen, pthreads, posix_spawn.
 *
 * The probe's subprocess is written by hand because it runs inside an arbitrary FMI host:
 * no shell (a path may hold any character), no popen (its stderr would reach the host's
 * terminal), and a deadline.
 */
#define _GNU_SOURCE /* dladdr, dl_iterate_phdr, RTLD_DEFAULT, RTLD_NOLOAD, pipe2 */
#include "glibc_floor.h"
#include "platform.h"

#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <link.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

#define NAME_MAX_PATH 4096

const char *const VENV_PYTHONS[] = {"bin/python3", "bin/python", NULL};
const PathPython PATH_PYTHONS[2] = {{"python3", NULL}, {"python", NULL}};

/* ---- locks, environment, files ------------------------------------------------------- */

static pthread_mutex_t locks[LOCKS] = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_MUTEX_INITIALIZER};

void platform_lock(int which) { pthread_mutex_lock(&locks[which]); }
void platform_unlock(int which) { pthread_mutex_unlock(&locks[which]); }

/* ThreadSanitizer sees no order in flock: in a build with it, taking and leaving the lock
 * are told to it, on one address every copy of the runtime in the process shares (flock's
 * own), so that what one copy did under the lock is seen as done before the next. */
#if defined(__SANITIZE_THREAD__)
#define TSAN_BUILD 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define TSAN_BUILD 1
#endif
#endif
#ifdef TSAN_BUILD
void __tsan_acquire(void *address);
void __tsan_release(void *address);
#define TOLD_ACQUIRED() __tsan_acquire((void *)flock)
#define TOLD_RELEASED() __tsan_release((void *)flock)
#else
#define TOLD_ACQUIRED() ((void)0)
#define TOLD_RELEASED() ((void)0)
#endif

void *platform_hold_python(const char *libpython)
{
    int fd = open(libpython, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return NULL;
    while (flock(fd, LOCK_EX) != 0) {
        if (errno != EINTR) {
            close(fd);
            return NULL;
        }
    }
    TOLD_ACQUIRED();
    return (void *)(intptr_t)(fd + 1); /* never NULL */
}

void platform_release_python(void *held)
{
    if (!held) return;
    int fd = (int)((intptr_t)held - 1);
    TOLD_RELEASED();
    flock(fd, LOCK_UN);
    close(fd);
}

const char *platform_getenv(const char *name, char *out, size_t size)
{
    const char *value = getenv(name);
    if (!value) return NULL;
    snprintf(out, size, "%s", value);
    return out;
}

FILE *platform_fopen(const char *path, const char *mode) { return fopen(path, mode); }

int path_exists(const char *path) { return path[0] && access(path, F_OK) == 0; }

int platform_is_directory(const char *path)
{
    int fd = open(path, O_RDONLY | O_DIRECTORY);
    if (fd < 0) return 0;
    close(fd);
    return 1;
}

int platform_same_file(const char *a, const char *b)
{
    char ra[PATH_MAX], rb[PATH_MAX];
    return realpath(a, ra) && realpath(b, rb) && !strcmp(ra, rb);
}

int own_path(char *out, size_t size)
{
    Dl_info info;
    /* an object of this library: a function's address as a pointer is no ISO C */
    if (!dladdr((const void *)VENV_PYTHONS, &info) || !info.dli_fname) return 0;
    return snprintf(out, size, "%s", info.dli_fname) < (int)size;
}

int platform_on_path(const char *name, char *out, size_t size)
{
    const char *path = getenv("PATH");
    while (path && *path) {
        size_t n = strcspn(path, ":");
        /* an entry whose joined path does not fit is passed over: cut short, it would
         * name another file (and a path that long cannot be opened: PATH_MAX) */
        int joined = n < size ? snprintf(out, size, "%.*s/%s", (int)n, n ? path : ".", name)
                              : -1;
        if (joined >= 0 && (size_t)joined < size && access(out, X_OK) == 0 &&
            !platform_is_directory(out)) {
            return 1;
        }
        path += n + (path[n] == ':');
    }
    out[0] = '\0';
    return 0;
}

void platform_local_path(char *path, size_t size)
{
    (void)path, (void)size;
}

/* ---- libraries ----------------------------------------------------------------------- */

void *platform_library_open(const char *path, int global)
{
    return dlopen(path, RTLD_NOW | (global ? RTLD_GLOBAL : RTLD_LOCAL));
}

void *platform_library_symbol(void *library, const char *name) { return dlsym(library, name); }

void platform_library_close(void *library) { dlclose(library); }

void platform_library_error(char *out, size_t size)
{
    const char *error = dlerror();
    snprintf(out, size, "%s", error ? error : "");
}

void *platform_open_wrapper(const char *path) { return platform_library_open(path, 0); }

extern int __cxa_atexit(void (*)(void *), void *, void *);

void platform_exit_handler(void (*finalize)(void *)) { __cxa_atexit(finalize, NULL, NULL); }

static int find_libpython(struct dl_phdr_info *info, size_t size, void *data)
{
    (void)size;
    char *found = data;
    if (info->dlpi_name && strstr(info->dlpi_name, "/libpython")) {
        snprintf(found, NAME_MAX_PATH, "%s", info->dlpi_name);
        return 1;
    }
    return 0;
}

int platform_loaded_python(void **library, char *file, size_t size)
{
    void *symbol = dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    Dl_info info;
    char found[NAME_MAX_PATH] = "";
    if (symbol && dladdr(symbol, &info) && info.dli_fname) {
        snprintf(file, size, "%s", info.dli_fname);
        *library = RTLD_DEFAULT;
        return 1;
    }
    dl_iterate_phdr(find_libpython, found); /* loaded with RTLD_LOCAL: not in dlsym's scope */
    snprintf(file, size, "%s", found);
    *library = found[0] ? dlopen(found, RTLD_NOW | RTLD_NOLOAD) : NULL;
    return *library != NULL;
}

/* ---- the probe's subprocess ---------------------------------------------------------- */

void buffer_append(Buffer *b, const char *data, size_t n)
{
    if (b->size + n > b->limit) n = b->limit - b->size;
    memcpy(b->data + b->size, data, n);
    b->size += n;
}

/* The host's environment without PYTHONHOME and PYTHONUTF8 (a pointer array; the strings
 * are shared). PYTHONUTF8 goes too because the Python the probe vouches for is started in
 * UTF-8 mode set before CPython reads its environment (runtime.c), which then never reads
 * PYTHONUTF8: a value a Python started on its own refuses (PYTHONUTF8=7) must not pass
 * over a Python the host can start. */
static char **child_environment(void)
{
    char **host = environ; /* read once */
    size_t n = 0;
    while (host && host[n]) n++;
    char **copy = calloc(n + 1, sizeof *copy);
    if (!copy) return NULL;
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        if (strncmp(host[i], "PYTHONHOME=", 11) && strncmp(host[i], "PYTHONUTF8=", 11)) {
            copy[j++] = host[i];
        }
    }
    return copy;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Read both pipes to their end or the deadline; 1 if both ended. */
static int drain(int out, int err, Buffer *stdout_text, Buffer *stderr_text, int timeout_s)
{
    struct pollfd fds[2] = {{out, POLLIN, 0}, {err, POLLIN, 0}};
    Buffer *into[2] = {stdout_text, stderr_text};
    double deadline = now() + timeout_s;
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
                buffer_append(into[i], chunk, (size_t)got);
            } else if (got == 0 || errno != EINTR) {
                fds[i].fd = -1;
            }
        }
    }
    return 1;
}

/* The probe started with stdin /dev/null, stdout and stderr the pipes' ends; 0, or the
 * error number: each file action is checked (one that failed for want of memory would
 * leave the child the host's own stdout and stderr). */
static int spawn(const char *const argv[], int out[2], int err[2], pid_t *pid)
{
    posix_spawn_file_actions_t actions;
    int failed = posix_spawn_file_actions_init(&actions);
    if (failed) return failed;
    char **env = child_environment();
    if (!env) failed = ENOMEM;
    if (!failed) failed = posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    if (!failed) failed = posix_spawn_file_actions_adddup2(&actions, out[1], 1);
    if (!failed) failed = posix_spawn_file_actions_adddup2(&actions, err[1], 2);
    /* posix_spawn takes char *const argv[] but does not write them (POSIX's rationale:
     * the old prototype kept for compatibility) */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wcast-qual"
    if (!failed) failed = posix_spawn(pid, argv[0], &actions, NULL, (char *const *)argv, env);
#pragma GCC diagnostic pop
    posix_spawn_file_actions_destroy(&actions);
    free(env);
    return failed;
}

void platform_run(const char *const argv[], int timeout_s, Buffer *text, Buffer *errors,
                  Ran *ran)
{
    int out[2] = {-1, -1}, err[2] = {-1, -1};
    pid_t pid = 0;
    int failed = pipe2(out, O_CLOEXEC) || pipe2(err, O_CLOEXEC) ? errno
                                                                : spawn(argv, out, err, &pid);
    if (out[1] >= 0) close(out[1]);
    if (err[1] >= 0) close(err[1]);
    if (failed) {
        ran->ending = RAN_NOT_STARTED;
        snprintf(ran->error, sizeof ran->error, "%s", strerror(failed));
    } else {
        int finished = drain(out[0], err[0], text, errors, timeout_s);
        if (!finished) kill(pid, SIGKILL);
        int status = 0;
        pid_t got; /* a signal the host catches without SA_RESTART interrupts the wait */
        do got = waitpid(pid, &status, 0);
        while (got < 0 && errno == EINTR);
        int waited = got == pid; /* not when the host ignores SIGCHLD */
        ran->ending = !finished                         ? RAN_TIMED_OUT
                      : waited && WIFSIGNALED(status) ? RAN_KILLED
                      : waited && WIFEXITED(status)   ? RAN_EXITED
                                                      : RAN_UNKNOWN;
        ran->code = ran->ending == RAN_KILLED   ? WTERMSIG(status)
                    : ran->ending == RAN_EXITED ? WEXITSTATUS(status)
                                                : 0;
    }
    if (out[0] >= 0) close(out[0]);
    if (err[0] >= 0) close(err[0]);
}
