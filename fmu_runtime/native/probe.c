/* Ask a candidate Python, in a subprocess, for its version, libpython, prefixes, search path
 * and whether it imports numpy (and has numba).
 *
 * Written by hand because it runs inside an arbitrary FMI host: no shell (a path may hold
 * any character), no popen (its stderr would reach the host's terminal), and a deadline.
 * The script is valid Python 2 and 3, so that an old `python` on PATH still says which
 * version it is; paths travel hex-encoded (any byte, any newline).
 */
#include "probe.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    "if os.name == 'nt':\n" /* the DLL this interpreter runs in, else the usual one */
    "    try:\n"
    "        import ctypes\n"
    "        b = ctypes.create_unicode_buffer(32768)\n"
    "        k = ctypes.windll.kernel32\n"
    "        if k.GetModuleFileNameW(ctypes.c_void_p(sys.dllhandle), b, 32768):\n"
    "            found = b.value\n"
    "    except Exception:\n"
    "        pass\n"
    "    n = os.path.join(sys.base_prefix, 'python%d%d.dll' % sys.version_info[:2])\n"
    "    if not found and os.path.isfile(n):\n"
    "        found = n\n"
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

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
}

/* Decode ``n`` hex digits of ``hex`` into ``out`` (NUL-terminated, truncated to size, and
 * up to the first that is not one): 1, or 0 when they did not fit. */
static int unhex(const char *hex, size_t n, char *out, size_t size)
{
    size_t j = 0, i = 0;
    for (; i + 1 < n && j + 1 < size; i += 2) {
        int high = hex_value(hex[i]), low = hex_value(hex[i + 1]);
        if (high < 0 || low < 0) break;
        out[j++] = (char)(high * 16 + low);
    }
    out[j] = '\0';
    return !(i + 1 < n && j + 1 >= size);
}

/* A path of the answer: cut short, it would name another file (a libpython loaded, a
 * standard library checked), so one that does not fit is remembered as too long. */
static void unhex_file(const char *key, const char *hex, size_t n, char *out, size_t size,
                       Answer *a)
{
    if (!unhex(hex, n, out, size) && !a->too_long[0]) {
        snprintf(a->too_long, sizeof a->too_long, "%s", key);
    }
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
        (void)unhex(text, n, out, n / 2 + 1); /* fits: each byte from two digits */
        out += strlen(out) + 1;
        a->paths++;
        text += n + (text[n] == ':');
    }
}

/* Lines end in "\n", or "\r\n" from a Windows Python (its stdout is in text mode). Split
 * by hand: strtok's hidden state is the host's too (a host looping over strtok around
 * fmi2Instantiate lost its place), and C11 has no strtok_r. */
static void parse(char *text, Answer *a)
{
    for (char *next = text; *next;) {
        char *line = next + strspn(next, "\r\n");
        next = line + strcspn(line, "\r\n");
        if (*next) *next++ = '\0';
        char *value = strchr(line, '=');
        if (!value) continue;
        *value++ = '\0';
        size_t n = strlen(value);
        if (!strcmp(line, "version")) {
            int v[3];
            if (read_version(value, 3, 1, v)) {
                a->major = v[0], a->minor = v[1], a->micro = v[2];
            } else { /* shown cut to 40 bytes, as said */
                snprintf(a->bad_version, sizeof a->bad_version, "%.*s%s",
                         (int)whole_characters(value, n > 40 ? 40 : n), value,
                         n > 40 ? "..." : "");
            }
        } else if (!strcmp(line, "implementation")) {
            snprintf(a->implementation, sizeof a->implementation, "%s", value);
        } else if (!strcmp(line, "libpython")) {
            unhex_file("libpython", value, n, a->libpython, sizeof a->libpython, a);
        } else if (!strcmp(line, "base_prefix")) {
            unhex_file("base_prefix", value, n, a->base_prefix, sizeof a->base_prefix, a);
        } else if (!strcmp(line, "stdlib")) {
            unhex_file("stdlib", value, n, a->stdlib, sizeof a->stdlib, a);
        } else if (!strcmp(line, "executable")) {
            unhex_file("executable", value, n, a->executable, sizeof a->executable, a);
        } else if (!strcmp(line, "path") && !a->path) {
            unhex_path(value, a);
        } else if (!strcmp(line, "numpy")) {
            snprintf(a->numpy, sizeof a->numpy, "%s", value);
        } else if (!strcmp(line, "numpy_error")) {
            (void)unhex(value, n, a->numpy_error, sizeof a->numpy_error); /* shown cut */
        } else if (!strcmp(line, "numba")) {
            a->numba = !strcmp(value, "yes");
        } else if (!strcmp(line, "end")) {
            a->answered = 1;
        }
    }
}

/* The last non-empty line of the child's stderr, or "" (the text ends there after). */
static const char *last_line(Buffer *b)
{
    while (b->size && (b->data[b->size - 1] == '\n' || b->data[b->size - 1] == '\r')) b->size--;
    b->data[b->size] = '\0';
    char *line = strrchr(b->data, '\n');
    return line ? line + 1 : b->data;
}

/* The line after ``line`` ("\n", "\r\n" or "\r" from a Windows Python), or NULL. */
static const char *next_line(const char *line)
{
    const char *end = line + strcspn(line, "\r\n");
    if (*end == '\r') end++;
    if (*end == '\n') end++;
    return *end ? end : NULL;
}

static int starts(const char *text, const char *start)
{
    return !strncmp(text, start, strlen(start));
}

#define FATAL "Fatal Python error: "

/* The exception CPython prints after its fatal line and "Python runtime state: ..."
 * (past a traceback, before the threads' stacks), or NULL when it prints none. */
static const char *fatal_exception(const char *fatal)
{
    const char *line = next_line(fatal);
    if (!line || !starts(line, "Python runtime state: ")) return NULL;
    for (line = next_line(line); line && strcspn(line, "\r\n"); line = next_line(line)) {
        if (starts(line, "Traceback (") || line[0] == ' ') continue;
        return starts(line, "Current thread") || starts(line, "Thread 0x") ? NULL : line;
    }
    return NULL;
}

/* What the child's stderr says of why it ended, into ``out`` (cut to whole characters):
 * CPython's "Fatal Python error: " line, where it names a variable of the environment it
 * refuses (PYTHONHASHSEED=garbage), with the exception after it, if any (PYTHONIOENCODING:
 * "LookupError: unknown encoding: bogus"); the lines that follow only say how far it got
 * ("Python runtime state: preinitialized", "<no Python frame>"). Else its last line. */
static void said_line(Buffer *b, char *out, size_t size)
{
    const char *line = last_line(b), *exception = NULL;
    for (const char *at = b->data; at; at = next_line(at)) {
        if (starts(at, FATAL)) {
            line = at;
            exception = fatal_exception(at);
            break;
        }
    }
    int n = (int)strcspn(line, "\r\n"); /* at most ERR_LIMIT */
    if (exception) {
        snprintf(out, size, "%.*s (%.*s)", n, line, (int)strcspn(exception, "\r\n"), exception);
    } else {
        snprintf(out, size, "%.*s", n, line);
    }
    out[whole_characters(out, strlen(out))] = '\0';
}

/* An exit status as a number (in hex when it is a Windows NTSTATUS such as 0xc0000005). */
static void exit_status(unsigned long code, char *out, size_t size)
{
    if (code > 255) snprintf(out, size, "0x%lx", code);
    else snprintf(out, size, "%lu", code);
}

#ifdef _WIN32
#define PATH_LIST ";"
#else
#define PATH_LIST ":"
#endif

/* The first folder on the host's PYTHONPATH that is a Python's standard library (holds
 * os.py), into ``out``, or 0. Every Python started here imports from it before its own,
 * and one of another version fails so before answering (3.9's: "AssertionError: SRE
 * module mismatch"); PYTHONHOME never reaches the probe (platform_run). */
static int stdlib_on_pythonpath(char *out, size_t size)
{
    char list[PATH_SIZE];
    if (!platform_getenv("PYTHONPATH", list, sizeof list)) return 0;
    for (const char *entry = list; *entry;) {
        size_t n = strcspn(entry, PATH_LIST);
        char os_py[PATH_SIZE + 8];
        snprintf(out, size, "%.*s", (int)n, entry);
        snprintf(os_py, sizeof os_py, "%s%sos.py", out, PATH_SEPARATOR);
        if (n && n < size && path_exists(os_py)) return 1;
        entry += n + (entry[n] == PATH_LIST[0]);
    }
    return 0;
}

/* Why a child that did not answer failed, from how it ended. */
static void explain(Answer *a, const Ran *ran, Buffer *err)
{
    char said[sizeof a->failure / 2];
    said_line(err, said, sizeof said);
    const char *sep = said[0] ? ": " : "";
    char status[32];
    exit_status(ran->code, status, sizeof status);
    if (ran->ending == RAN_TIMED_OUT) {
        snprintf(a->failure, sizeof a->failure, "gave no answer within %d s", PROBE_TIMEOUT_S);
    } else if (ran->ending == RAN_KILLED) {
        snprintf(a->failure, sizeof a->failure, "was killed by signal %lu%s%s", ran->code, sep,
                 said);
    } else if (ran->ending == RAN_EXITED && ran->code == 0) {
        snprintf(a->failure, sizeof a->failure, "gave no answer the runtime understands%s%s",
                 sep, said);
    } else if (ran->ending == RAN_EXITED) {
        char stdlib[PATH_SIZE];
        int foreign = stdlib_on_pythonpath(stdlib, sizeof stdlib);
        snprintf(a->failure, sizeof a->failure, "exited with status %s before answering%s%s%s%s%s",
                 status, sep, said,
                 foreign ? " (the environment's PYTHONPATH holds a Python's standard library, "
                         : "",
                 foreign ? stdlib : "",
                 foreign ? ", which a Python of another version cannot start with: unset "
                           "PYTHONPATH, or leave that folder out of it)"
                         : "");
    } else {
        snprintf(a->failure, sizeof a->failure, "did not answer%s%s", sep, said);
    }
}

void probe(const char *executable, const char *argument, Answer *a)
{
    memset(a, 0, sizeof *a);
    const char *argv[] = {executable, argument, "-c", SCRIPT, NULL};
    if (!argument) memmove(&argv[1], &argv[2], 3 * sizeof argv[0]);
    Buffer text = {malloc(OUT_LIMIT + 1), 0, OUT_LIMIT};
    Buffer errors = {malloc(ERR_LIMIT + 1), 0, ERR_LIMIT};
    Ran ran = {RAN_NOT_STARTED, 0, "out of memory"};
    if (text.data && errors.data) platform_run(argv, PROBE_TIMEOUT_S, &text, &errors, &ran);
    if (ran.ending == RAN_NOT_STARTED) {
        snprintf(a->failure, sizeof a->failure, "could not be run (%s)", ran.error);
    } else {
        text.data[text.size] = '\0';
        parse(text.data, a);
        if (!a->answered) explain(a, &ran, &errors);
    }
    free(text.data);
    free(errors.data);
}
