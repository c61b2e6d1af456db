/* The FMU's binary: the FMI 2.0 co-simulation functions. Each enforces the standard's call
 * sequence and the variables' declared rules, then hands the call to a backend: the FMU's
 * Python slave called directly (slave.c), or pythonfmu's own binary (forward.c,
 * AUV_FMU_RUNTIME=pythonfmu).
 *
 * Written by hand because no library does it: pythonfmu's binary returns fmi2OK from every
 * function but doStep whatever the Python side decides, crashes on NULL arguments, and
 * needs its host to have started Python.
 *
 * Refused without calling Python, with fmi2Error (NULL from fmi2Instantiate), one Error
 * logged and nothing changed: a NULL instance name, resource location or GUID, an empty
 * instance name (or one of white space), a resource location of another scheme than file:
 * or with %00 in it, a GUID that is not this build's; a NULL value-reference, value or byte array (n > 0); a call
 * out of the FMI 2.0 co-simulation sequence (instantiated -> initialisation mode ->
 * initialised -> terminated; the error state after a failed initialisation or a fatal
 * error); a doStep whose step is not a finite number > 0, whose end t + h is not a finite
 * time after t (a step of 1e308 s from 1.7e308 s, or of 1e-3 s from 1e17 s), or whose
 * currentCommunicationPoint is not the FMU's current time (the start time, then the end
 * of the last step) within a relative 1e-9; a read of an unknown value reference or of
 * the wrong type; a write of a variable that cannot be written then (outputs, locals,
 * constants; a fixed parameter after initialisation, unless it is the value it has, or
 * the one a state set since gave it), of a non-finite Real, of a value outside the
 * declared min/max, or of a String that is not UTF-8; input derivatives the FMU does not
 * take; an FMU state another FMU took, or a pointer that is no FMU state alive in the
 * process (freed already, the host's own memory, garbage: never read). With the default
 * backend the values themselves are read and written in C (values.c): a Real read back
 * non-finite is refused there. The variables' rules come from resources/fmu_variables.txt,
 * the GUID and the slave class from resources/fmu_runtime.txt; the build writes both.
 *
 * Refusals made in Python (fmu_runtime/safe_slave.py logs each with status Error): the
 * backends pass every message the slave logs to the host's logger, with a category
 * (never NULL), and remember the worst status logged during the current call: a call
 * during which an Error was logged returns fmi2Error (a refused doStep keeps its
 * fmi2Discard), even when the host's logger calls the FMU back meanwhile (each call keeps
 * its own). OK-status messages reach the host only while it has logging on.
 *
 * Once the interpreter has shut down under live instances (a Python host exiting without
 * freeing them, then destructors calling fmi2Terminate or fmi2FreeInstance), every call
 * returns fmi2Error without a message (the host's logger may be Python code) and
 * fmi2FreeInstance frees only C memory.
 */
#include "loader.h"
#include "python.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const PHASES[] = {"instantiated", "in initialisation mode", "initialised",
                                     "terminated", "in the error state"};
#define TIME_TOLERANCE 1e-9 /* relative: masters compute t_n = n h */

typedef struct Saved {
    unsigned magic;
    int phase;
    double time;
    void *inner;  /* the backend's state */
    uint32_t fmu; /* which FMU saved it: the CRC-32 of its GUID (fmu_of) */
    unsigned format; /* whose ``inner`` it is: serial_magic of the backend that took it */
    Instance *owner;           /* the instance that took it, which frees it if the host */
    struct Saved *prev, *next; /* does not: its states alive (Instance.states) */
} Saved;
#define SAVED_MAGIC 0x4155564cu /* "AUVL" */
#define FORWARDED_MAGIC 0x41555650u /* "AUVP": serialised on pythonfmu's runtime */
/* A serialised state: the magic of the backend that wrote it (serial_magic), phase, time,
 * the FMU that took it (Saved's fmu), then the CRC-32 of every byte but its own four,
 * then the backend's bytes. */
#define SAVED_FMU (sizeof(unsigned) + sizeof(int) + sizeof(double))
#define SAVED_CRC (SAVED_FMU + sizeof(uint32_t))
#define SAVED_HEADER (SAVED_CRC + sizeof(uint32_t))

/* CRC-32 (IEEE 802.3, zlib's) of ``n`` bytes, continuing from ``crc`` (0 to start). Written
 * here because the runtime links nothing but the C library; bitwise, as a state is
 * serialised now and then, never per step. */
static uint32_t crc32_of(uint32_t crc, const fmi2Byte *bytes, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= (unsigned char)bytes[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

/* The CRC-32 of a serialised state of ``size`` bytes, its own field left out. */
static uint32_t state_crc(const fmi2Byte *bytes, size_t size)
{
    return crc32_of(crc32_of(0, bytes, SAVED_CRC), bytes + SAVED_HEADER, size - SAVED_HEADER);
}

/* ---- logging ------------------------------------------------------------------------ */

static const char *category_of(fmi2Status status)
{
    static const char *const names[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                        "logStatusError", "logStatusFatal", "logAll"};
    return status <= fmi2Pending ? names[status] : "logAll";
}

/* ``message`` (a printf format without conversions: every % doubled) on stderr as the
 * host's printf would show it, with its instance and status, for a host with no logger. */
static void to_stderr(const char *instance, fmi2Status status, const char *message)
{
    static const char *const labels[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};
    fprintf(stderr, "%s: [%s] ", instance ? instance : "FMU",
            status <= fmi2Pending ? labels[status] : "?");
    for (const char *at = message; *at; at++) {
        if (at[0] == '%' && at[1] == '%') at++;
        fputc(*at, stderr);
    }
    fputc('\n', stderr);
}

static void emit(const fmi2CallbackFunctions *host, const char *instance, fmi2Status status,
                 const char *category, const char *message)
{
    if (host && host->logger) {
        host->logger(host->componentEnvironment, instance, status,
                     category ? category : category_of(status), message);
    } else {
        to_stderr(instance, status, message);
    }
}

static int category_index(const Instance *c, const char *name);
static fmi2Status tell_debug(Instance *c, int told);

void instance_log(Instance *c, fmi2Status status, const char *category, const char *message)
{
    if (status > c->logged) c->logged = status;
    fmi2Status worst = c->logged;
    int index = c->debugged && category ? category_index(c, category) : -1;
    int debugged = index >= 0 && index < 64 && (c->debugged >> index & 1);
    if (c->logging || status >= fmi2Warning || debugged) {
        emit(&c->host, c->name, status, category, message);
    }
    c->logged = worst; /* a call the host's logger made meanwhile started from fmi2OK */
}

/* How many of the first ``n`` bytes of ``text`` (UTF-8) to keep so that a cut there
 * splits no character: an incomplete sequence at the end is left out, as a host may
 * refuse or crash on a message that is not UTF-8. */
size_t whole_characters(const char *text, size_t n)
{
    size_t start = n;
    while (start > 0 && n - start < 4 && ((unsigned char)text[start - 1] & 0xC0) == 0x80) {
        start--;
    }
    if (start == 0 || ((unsigned char)text[start - 1] & 0xC0) != 0xC0) return n;
    unsigned char lead = (unsigned char)text[start - 1];
    size_t length = lead >= 0xF0 ? 4 : lead >= 0xE0 ? 3 : 2;
    return n - (start - 1) >= length ? n : start - 1;
}

/* The length of the character at ``p`` if it is UTF-8 as Python's strict decoder takes it
 * (no overlong form, no surrogate, nothing above U+10FFFF), else 0 (0 at the end too). By
 * hand: the C library decodes only in the locale's encoding. */
static size_t utf8_character(const unsigned char *p)
{
    size_t n = p[0] < 0x80 ? 1 : p[0] < 0xC2 ? 0 : p[0] < 0xE0 ? 2 : p[0] < 0xF0 ? 3
             : p[0] < 0xF5 ? 4 : 0; /* 0x80-0xC1: a continuation or overlong lead */
    unsigned long code = n == 1 ? p[0] : p[0] & (0x7Fu >> n);
    for (size_t k = 1; k < n; k++) { /* each checked before the next is read: no overrun */
        if ((p[k] & 0xC0) != 0x80) return 0;
        code = (code << 6) | (p[k] & 0x3F);
    }
    if ((n == 3 && (code < 0x800 || (code >= 0xD800 && code <= 0xDFFF))) ||
        (n == 4 && (code < 0x10000 || code > 0x10FFFF))) {
        return 0;
    }
    return p[0] ? n : 0;
}

/* Each piece whole or not at all: a character, a doubled %, or a byte that is no UTF-8
 * shown as \xNN (Python's backslashreplace): a host's GUID, path or category quoted in a
 * refusal may be any bytes, and a host may refuse or crash on a message that is not UTF-8. */
void escape(const char *text, char *out, size_t size)
{
    size_t j = 0;
    for (const unsigned char *p = (const unsigned char *)text; *p;) {
        char piece[8];
        size_t n = utf8_character(p), m = n;
        if (!n) {
            m = (size_t)snprintf(piece, sizeof piece, "\\x%02x", p[0]);
            n = 1;
        } else if (p[0] == '%') {
            m = 2;
            memcpy(piece, "%%", m);
        } else {
            memcpy(piece, p, n);
        }
        if (j + m >= size) break;
        memcpy(out + j, piece, m);
        j += m;
        p += n;
    }
    out[j] = '\0';
}

/* The offset of the first byte of ``text`` that is no UTF-8 as Python's strict decoder
 * takes it (a stray continuation byte, a sequence cut short, an overlong form, a
 * surrogate, a code above U+10FFFF), or -1 if there is none. */
static long not_utf8_at(const char *text)
{
    const unsigned char *p = (const unsigned char *)text;
    long i = 0;
    for (size_t n; p[i]; i += (long)n) {
        if (!(n = utf8_character(p + i))) return i;
    }
    return -1;
}

/* ``text``, which fills its ``size`` bytes (snprintf may have cut it short), ended between
 * characters: escape() would show a character cut in two as bytes that are no UTF-8. */
static void cut_whole(char *text, size_t size)
{
    size_t n = strlen(text);
    if (n + 1 == size) text[whole_characters(text, n)] = '\0';
}

fmi2Status refuse(Instance *c, const char *format, ...)
{
    char text[LINE_SIZE], escaped[2 * LINE_SIZE];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    cut_whole(text, sizeof text);
    escape(text, escaped, sizeof escaped);
    instance_log(c, fmi2Error, "logStatusError", escaped);
    return fmi2Error;
}

/* A refusal before an instance exists: to the host's logger, or stderr without one. */
static void refuse_instantiation(const fmi2CallbackFunctions *host, const char *name,
                                 const char *text)
{
    char escaped[2 * LINE_SIZE];
    escape(text, escaped, sizeof escaped);
    emit(host, name ? name : "FMU", fmi2Error, "logStatusError", escaped);
}

/* What the backend answered, raised to fmi2Error if an Error was logged meanwhile. */
static fmi2Status answer(Instance *c, fmi2Status status)
{
    if (status == fmi2Fatal || c->logged == fmi2Fatal) {
        c->phase = FAILED;
        return fmi2Fatal;
    }
    return status < fmi2Discard && c->logged >= fmi2Error ? fmi2Error : status;
}

/* Shortest text that reads back as the same double, like Python's repr. */
#define SHOW_SIZE 32 /* show's out: loader.h */

/* By hand: C has no shortest-repr printf (%g and %e print as many digits as asked), so
 * the digits are the fewest, of 1 to 17, that strtod reads back as ``x``; they are then
 * laid out as Python's repr lays them out (positional for exponents -4 to 15, else
 * d.ddde+XX), so that a line of the runtime and one of the slave name a value alike. */
const char *show(double x, char *out)
{
    if (isnan(x)) return strcpy(out, "nan");
    if (isinf(x)) return strcpy(out, x > 0 ? "inf" : "-inf");
    char shortest[40]; /* [-]d[.ddd]e(+|-)XX; 17 digits always read back */
    for (int precision = 0; precision <= 16; precision++) {
        snprintf(shortest, sizeof shortest, "%.*e", precision, x);
        if (strtod(shortest, NULL) == x) break;
    }
    char digits[24];
    size_t n = 0;
    const char *at = shortest;
    for (; *at && *at != 'e'; at++) { /* the digits alone: no sign, no decimal point */
        if (isdigit((unsigned char)*at) && n < sizeof digits - 1) digits[n++] = *at;
    }
    digits[n] = '\0';
    int exponent = *at ? atoi(at + 1) : 0;
    size_t used = 0;
    if (signbit(x)) out[used++] = '-';
    if (exponent < -4 || exponent >= 16) { /* 5e-324, 1e+16, 1.5e+300 */
        out[used++] = digits[0];
        snprintf(out + used, SHOW_SIZE - used, "%s%se%+03d", n > 1 ? "." : "", digits + 1,
                 exponent);
    } else if (exponent < 0) { /* 0.0001, 0.1 */
        snprintf(out + used, SHOW_SIZE - used, "0.%.*s%s", -exponent - 1, "000", digits);
    } else { /* 1.5, 100000.0, 1000000000000000.0 */
        for (int i = 0; i <= exponent; i++) out[used++] = (size_t)i < n ? digits[i] : '0';
        snprintf(out + used, SHOW_SIZE - used, ".%s",
                 (size_t)exponent + 1 < n ? digits + exponent + 1 : "0");
    }
    return out;
}

/* By hand: the C library has no checked sscanf (its %d and %u are undefined behaviour on
 * a number that does not fit); strtoul reports ERANGE, but takes a sign and leading
 * spaces, which a version or a value reference never has. */
int read_number(const char **text, unsigned long most, unsigned long *out)
{
    if (!isdigit((unsigned char)**text)) return 0;
    char *end;
    errno = 0;
    unsigned long value = strtoul(*text, &end, 10);
    if (errno == ERANGE || value > most) return 0;
    *text = end;
    *out = value;
    return 1;
}

int read_version(const char *text, int parts, int whole, int numbers[3])
{
    const char *p = text;
    for (int i = 0; i < parts; i++) {
        unsigned long n;
        if ((i && *p++ != '.') || !read_number(&p, INT_MAX, &n)) break;
        numbers[i] = (int)n;
        if (i + 1 == parts && (!whole || !*p)) return 1;
    }
    numbers[0] = numbers[1] = numbers[2] = 0;
    return 0;
}

/* ---- the build's records ------------------------------------------------------------ */

static int grow(Instance *c, unsigned vr)
{
    if (vr < c->count) return 1;
    Variable *grown = realloc(c->vars, (vr + 1) * sizeof *grown);
    if (!grown) return 0;
    memset(grown + c->count, 0, (vr + 1 - c->count) * sizeof *grown);
    c->vars = grown;
    c->count = vr + 1;
    return 1;
}

/* Each variable's slot: its index among the variables of its type in value-reference
 * order (value_buffers.py numbers them the same way); room for the String copies. */
static int number_slots(Instance *c)
{
    Values *v = &c->values;
    for (size_t vr = 0; vr < c->count; vr++) {
        Variable *var = &c->vars[vr];
        if (!var->known) continue;
        size_t *n = var->type == 'R'   ? &v->reals_n
                    : var->type == 'I' ? &v->integers_n
                    : var->type == 'B' ? &v->booleans_n
                                       : &v->strings_n;
        var->slot = (int)(*n)++;
    }
    v->strings = calloc(v->strings_n + 1, sizeof(char *));
    v->dirty = calloc(v->strings_n + 1, 1);
    return v->strings && v->dirty;
}

/* The next space-separated word of ``*line`` into ``out``: 1, or 0 when there is none or
 * it does not fit (never cut short: a bound cut short is another number). */
static int next_word(const char **line, char *out, size_t size)
{
    const char *p = *line + strspn(*line, " ");
    size_t n = strcspn(p, " \r\n");
    if (!n || n >= size) return 0;
    memcpy(out, p, n);
    out[n] = '\0';
    *line = p + n;
    return 1;
}

/* A bound or start value: "-" for none (``none``), else a number written whole. */
static int read_bound(const char *text, double none, double *out)
{
    if (!strcmp(text, "-")) {
        *out = none;
        return 1;
    }
    char *end;
    *out = strtod(text, &end);
    return end != text && !*end;
}

/* The value references index an array (grow): a bound on its size. */
#define MOST_VR 100000UL

/* One line "vr type causality variability min max start name" ("-" for none) into the
 * instance's table: NULL, or what is wrong with it. */
static const char *read_variable(Instance *c, const char *line, char *why, size_t n)
{
    char vr_text[24], type[2], causality[24], variability[16], min[BOUND_SIZE],
        max[BOUND_SIZE], start[BOUND_SIZE], name[NAME_SIZE];
    char *words[] = {vr_text, type, causality, variability, min, max, start, name};
    const size_t sizes[] = {sizeof vr_text, sizeof type, sizeof causality, sizeof variability,
                            sizeof min, sizeof max, sizeof start, sizeof name};
    static const char *const fields[] = {"a value reference", "a type", "a causality",
                                         "a variability", "a min", "a max", "a start",
                                         "a name"};
    const char *p = line;
    for (size_t i = 0; i < 8; i++) {
        if (!next_word(&p, words[i], sizes[i])) {
            const char *found = p + strspn(p, " ");
            size_t length = strcspn(found, " \r\n");
            snprintf(why, n, "%s of at most %zu bytes expected, found %s%.*s%s", fields[i],
                     sizes[i] - 1, length ? "\"" : "nothing",
                     (int)whole_characters(found, length < 64 ? length : 64), found,
                     length > 64 ? "...\"" : length ? "\"" : "");
            return why;
        }
    }
    const char *digits = vr_text;
    unsigned long vr;
    double low, high, value;
    if (!read_number(&digits, MOST_VR, &vr) || *digits) {
        snprintf(why, n, "value reference %s is not a whole number from 0 to %lu", vr_text,
                 MOST_VR);
    } else if (!strchr("RIBS", type[0]) || type[1]) {
        snprintf(why, n, "type %s is not R, I, B or S", type);
    } else if (!read_bound(min, -(double)INFINITY, &low) ||
               !read_bound(max, (double)INFINITY, &high) ||
               !read_bound(start, (double)NAN, &value)) {
        snprintf(why, n, "min %s, max %s or start %s is neither a number nor -", min, max, start);
    } else if (!grow(c, (unsigned)vr)) {
        snprintf(why, n, "out of memory");
    } else if (c->vars[vr].known) { /* an FMI 2.0 alias: one slot would hold two rules */
        snprintf(why, n, "value reference %lu is declared twice (%s and %s): aliases are not "
                 "supported", vr, c->vars[vr].name, name);
    } else {
        Variable *v = &c->vars[vr];
        v->known = 1;
        v->type = type[0];
        snprintf(v->causality, sizeof v->causality, "%s", causality);
        snprintf(v->variability, sizeof v->variability, "%s", variability);
        snprintf(v->min, sizeof v->min, "%s", strcmp(min, "-") ? min : "");
        snprintf(v->max, sizeof v->max, "%s", strcmp(max, "-") ? max : "");
        v->low = low;
        v->high = high;
        v->start = v->value = value;
        snprintf(v->name, sizeof v->name, "%s", name);
        return NULL;
    }
    return why;
}

/* The variables' table, resources/fmu_variables.txt (the build writes it from
 * modelDescription.xml): 1, or 0 with why not (a line that cannot be read whole refuses
 * the FMU: skipped, or cut short, it would leave a variable with other rules). */
static int read_variables(Instance *c, char *why, size_t n)
{
    char path[PATH_SIZE + 32], line[512], wrong[LINE_SIZE / 2];
    snprintf(path, sizeof path, "%s%s%s", c->resources, PATH_SEPARATOR, VARIABLES_FILE);
    FILE *in = platform_fopen(path, "r");
    if (!in) {
        snprintf(why, n, "%s is missing", path);
        return 0;
    }
    const char *bad = NULL;
    unsigned long number = 0;
    while (!bad && fgets(line, sizeof line, in)) {
        number++;
        if (!strchr(line, '\n') && !feof(in)) {
            snprintf(wrong, sizeof wrong, "the line is longer than %zu bytes", sizeof line - 2);
            bad = wrong;
        } else if (line[strspn(line, " \r\n")]) { /* an empty line says nothing */
            bad = read_variable(c, line, wrong, sizeof wrong);
        }
    }
    fclose(in);
    if (bad) {
        snprintf(why, n, "%s line %lu: %s", path, number, bad);
        return 0;
    }
    if (!number_slots(c)) {
        snprintf(why, n, "out of memory for the variables of %s", path);
        return 0;
    }
    return 1;
}

/* key=value lines; unknown keys are ignored. NULL, or the key whose value (or line) does
 * not fit whole: cut short, a build's Python would name another file. */
static const char *read_record(const char *resources, Record *r)
{
    char path[PATH_SIZE + 32], line[PATH_SIZE + 64];
    snprintf(path, sizeof path, "%s%s%s", resources, PATH_SEPARATOR, RECORD_FILE);
    memset(r, 0, sizeof *r);
    FILE *in = platform_fopen(path, "r");
    if (!in) return "";
    struct {
        const char *key;
        char *value;
        size_t size;
    } keys[] = {{"guid", r->guid, sizeof r->guid},
                {"package", r->package, sizeof r->package},
                {"module", r->module, sizeof r->module},
                {"class", r->slave_class, sizeof r->slave_class},
                {"build_python", r->build_python, sizeof r->build_python},
                {"log_categories", r->log_categories, sizeof r->log_categories}};
    const char *too_long = NULL;
    while (!too_long && fgets(line, sizeof line, in)) {
        if (!strchr(line, '\n') && !feof(in)) too_long = "a line";
        line[strcspn(line, "\r\n")] = '\0';
        char *value = strchr(line, '=');
        if (too_long || !value) continue;
        *value++ = '\0';
        for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++) {
            if (strcmp(line, keys[i].key)) continue;
            int kept = snprintf(keys[i].value, keys[i].size, "%s", value);
            if (kept < 0 || (size_t)kept >= keys[i].size) too_long = keys[i].key;
        }
        if (!strcmp(line, "interpolates_inputs")) r->interpolates_inputs = !strcmp(value, "1");
    }
    fclose(in);
    if (too_long) return too_long;
    return r->guid[0] && r->package[0] && r->module[0] && r->slave_class[0] ? NULL : "";
}

/* ---- the variables' rules ----------------------------------------------------------- */

static const char *type_name(char type)
{
    return type == 'R' ? "Real" : type == 'I' ? "Integer" : type == 'B' ? "Boolean" : "String";
}

static const Variable *variable(const Instance *c, fmi2ValueReference vr)
{
    return vr < c->count && c->vars[vr].known ? &c->vars[vr] : NULL;
}

static int is_fixed_parameter(const Variable *v)
{
    return v->known && !strcmp(v->causality, "parameter") && !strcmp(v->variability, "fixed");
}

static void show_value(char type, double x, char *out)
{
    if (type == 'I') snprintf(out, 40, "%d", (int)x);
    else if (type == 'B') strcpy(out, x != 0 ? "True" : "False");
    else if (type == 'S') strcpy(out, "the string");
    else show(x, out);
}

/* "an" before a word that starts with a vowel ("an Integer", "an output"), else "a". */
static const char *article(const char *word)
{
    return word[0] && strchr("aeiouAEIOU", word[0]) ? "an" : "a";
}

/* Why writing ``x`` (a String's is NAN; ``same`` says whether it is the String the
 * variable has) to ``vr`` now is refused, or NULL. The value is formatted only for a
 * refusal: formatting costs more than every check together. */
static const char *write_refusal(const Instance *c, fmi2ValueReference vr, char type, double x,
                                 int same, char *why, size_t n)
{
    const Variable *v = variable(c, vr);
    if (!v) {
        snprintf(why, n, "set%s of valueReference %u refused: no such variable", type_name(type),
                 vr);
        return why;
    }
    const char *problem = NULL;
    if (v->type != type) {
        snprintf(why, n, "%s is %s %s, not %s %s", v->name, article(type_name(v->type)),
                 type_name(v->type), article(type_name(type)), type_name(type));
        return why;
    } else if (type == 'R' && !isfinite(x)) {
        problem = "expected a finite number";
    } else if (x < v->low || x > v->high) {
        problem = "range";
    } else if (!strcmp(v->variability, "constant")) {
        problem = "a constant cannot be set";
    } else if (!strcmp(v->causality, "input") ||
               (!strcmp(v->causality, "parameter") && strcmp(v->variability, "fixed"))) {
        return NULL;
    } else if (!strcmp(v->causality, "parameter")) {
        if (c->phase <= INITIALIZATION || (type == 'S' ? same : x == v->value)) return NULL;
        problem = "a fixed parameter can only be set before initialisation";
    }
    char shown[40];
    show_value(type, x, shown);
    if (!problem) {
        snprintf(why, n, "%s = %s refused: %s %s cannot be set", v->name, shown,
                 article(v->causality), v->causality);
    } else if (!strcmp(problem, "range")) {
        snprintf(why, n, "%s = %s refused: expected %s%s%s%s%s", v->name, shown, v->min,
                 v->min[0] ? " <= " : "", v->name, v->max[0] ? " <= " : "", v->max);
    } else {
        snprintf(why, n, "%s = %s refused: %s", v->name, shown, problem);
    }
    return why;
}

/* 1 if ``text`` is UTF-8 as Python's strict decoder takes it (no overlong form, no
 * surrogate, nothing above U+10FFFF): the slave is handed every String as a str, by
 * either backend (pythonfmu's binary does not survive one that is not). */
static int is_utf8(const unsigned char *text)
{
    return not_utf8_at((const char *)text) < 0;
}

/* NULL arrays (n > 0) are refused: FMI hosts pass them, and reading one would crash. */
#define NEED(array, what, call)                                                          \
    if (n > 0 && !(array)) return refuse(c, "%s refused: the %s is NULL (n = %zu)", call, \
                                         what, n)

/* 1 if ``text`` is the value of the String ``vr``, a fixed parameter written after
 * initialisation (read from the backend only then: a host re-applying its start values). */
static int same_string(Instance *c, fmi2ValueReference vr, const char *text)
{
    const Variable *v = variable(c, vr);
    fmi2String now = NULL;
    if (!text || !v || v->type != 'S' || !is_fixed_parameter(v) || c->phase <= INITIALIZATION) {
        return 0;
    }
    return c->backend->get(c, 'S', &vr, 1, &now) <= fmi2Warning && now && !strcmp(now, text);
}

/* An input's or a tunable parameter's value ``x`` refused for itself (not finite, beyond
 * its min/max) stands until a valid value is written: each doStep meanwhile is discarded
 * naming it, as the step would take the old value (fmu_runtime/safe_slave.py does the
 * same where pythonfmu's binary runs the FMU; docs/hosts.md states it). */
static void stand_refusal(Instance *c, fmi2ValueReference vr, char type, double x)
{
    Variable *v = vr < c->count && c->vars[vr].known ? &c->vars[vr] : NULL;
    if (!v || v->type != type || type == 'S' || !strcmp(v->variability, "constant")) return;
    if (strcmp(v->causality, "input") &&
        (strcmp(v->causality, "parameter") || !strcmp(v->variability, "fixed"))) {
        return;
    }
    if (!((type == 'R' && !isfinite(x)) || x < v->low || x > v->high)) return;
    if (!v->refused) c->refusals++;
    v->refused = 1;
    v->refused_value = x;
}

static void clear_refusal(Instance *c, fmi2ValueReference vr)
{
    if (c->vars[vr].refused) {
        c->vars[vr].refused = 0;
        c->refusals--;
    }
}

/* Check every value first: a refused call writes nothing. */
static fmi2Status check_writes(Instance *c, const fmi2ValueReference vr[], size_t n, char type,
                               const double *values, const fmi2String *strings)
{
    char why[512];
    if (c->phase >= TERMINATED) {
        return refuse(c, "fmi2Set%s refused: the FMU is %s", type_name(type), PHASES[c->phase]);
    }
    for (size_t i = 0; i < n; i++) {
        int same = strings && same_string(c, vr[i], strings[i]);
        double x = values ? values[i] : (double)NAN;
        if (write_refusal(c, vr[i], type, x, same, why, sizeof why)) {
            stand_refusal(c, vr[i], type, x);
            return refuse(c, "%s", why);
        }
    }
    return fmi2OK;
}

/* Reads of unknown value references or of the wrong type are refused; so are, before
 * initialisation mode, reads of a variable without a start value (the outputs declared
 * initial="calculated"): it has no value until the FMU computes it there, and its slot
 * would answer 0.0 as if it were one. FMI 2.0's state table allows no fmi2Get* before
 * initialisation mode (the Reference FMUs refuse them all); the parameters and inputs are
 * still answered there (their start, or the value written), as hosts read them to show or
 * check them. */
static fmi2Status check_reads(Instance *c, const fmi2ValueReference vr[], size_t n, char type)
{
    int early = c->phase == INSTANTIATED;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(c, vr[i]);
        if (!v) {
            return refuse(c, "get%s of valueReference %u refused: no such variable",
                          type_name(type), vr[i]);
        }
        if (v->type != type) {
            return refuse(c, "get%s refused: %s is %s %s, not %s %s", type_name(type), v->name,
                          article(type_name(v->type)), type_name(v->type),
                          article(type_name(type)), type_name(type));
        }
        if (early && type != 'S' && isnan(v->start)) {
            return refuse(c, "get%s refused: %s has no value before initialisation mode (it "
                          "is computed there: call enterInitializationMode, then read it)",
                          type_name(type), v->name);
        }
    }
    return fmi2OK;
}

static void remember_writes(Instance *c, const fmi2ValueReference vr[], size_t n,
                            const double *values)
{
    for (size_t i = 0; i < n; i++) {
        c->vars[vr[i]].value = values[i];
        clear_refusal(c, vr[i]);
    }
}

/* Every refused value standing forgotten: the values in use are the start values again
 * (fmi2Reset), or a state's (fmi2SetFMUstate), each valid. */
static void clear_refusals(Instance *c)
{
    for (size_t i = 0; c->refusals && i < c->count; i++) {
        clear_refusal(c, (fmi2ValueReference)i);
    }
}

static void reset_values(Instance *c)
{
    for (size_t i = 0; i < c->count; i++) c->vars[i].value = c->vars[i].start;
    clear_refusals(c);
}

/* After a state is set: the fixed parameters' values are the state's, so that a write of
 * the value a parameter has is taken and any other refused, as before. With the value
 * buffers they are read from their slots: a read through fmi2Get* in initialisation mode
 * would first compute the outputs to start from (the slave's _initialize), and a state
 * taken before they could be (a parameter still unusable) would make the state's setting,
 * done by then, answer fmi2Error. pythonfmu's binary is asked (one call per type); its
 * status is the read's own, not raised by what the slave logs meanwhile. */
static fmi2Status remember_state_values(Instance *c)
{
    if (c->values.flags) {
        for (size_t i = 0; i < c->count; i++) {
            if (is_fixed_parameter(&c->vars[i]) && c->vars[i].type != 'S') {
                c->vars[i].value = values_slot(c, (fmi2ValueReference)i);
            }
        }
        return fmi2OK;
    }
    if (!c->count) return fmi2OK; /* no variables: malloc(0) may answer NULL, no shortage */
    fmi2ValueReference *vr = malloc(c->count * sizeof *vr);
    double *reals = malloc(c->count * sizeof *reals);
    int *ints = malloc(c->count * sizeof *ints);
    fmi2Status s = vr && reals && ints ? fmi2OK : refuse(c, "fmi2SetFMUstate: out of memory");
    const char types[] = {'R', 'I', 'B'};
    for (int t = 0; s <= fmi2Warning && t < 3; t++) {
        size_t n = 0;
        for (size_t i = 0; i < c->count; i++) {
            if (is_fixed_parameter(&c->vars[i]) && c->vars[i].type == types[t]) {
                vr[n++] = (fmi2ValueReference)i;
            }
        }
        if (!n) continue;
        s = c->backend->get(c, types[t], vr, n, types[t] == 'R' ? (void *)reals : (void *)ints);
        for (size_t k = 0; s <= fmi2Warning && k < n; k++) {
            c->vars[vr[k]].value = types[t] == 'R' ? reals[k] : ints[k];
        }
    }
    free(vr);
    free(reals);
    free(ints);
    return s;
}

/* ---- instantiate / free ------------------------------------------------------------- */

/* The value of a hexadecimal digit, or -1. */
static int hex_digit(char ch)
{
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

/* The length of the scheme ``uri`` starts with (RFC 3986: a letter, then letters,
 * digits, +, - or ., then a colon; the colon not counted), or 0. */
static size_t scheme_length(const char *uri)
{
    size_t n = 0;
    while (isalpha((unsigned char)uri[n]) ||
           (n && uri[n] && (isdigit((unsigned char)uri[n]) || strchr("+-.", uri[n])))) {
        n++;
    }
    return uri[n] == ':' ? n : 0;
}

/* 1 if ``text`` starts with ``lower`` (lower-case ASCII) in any case. By hand:
 * strncasecmp is POSIX only, and follows the locale. */
static int starts_in_any_case(const char *text, const char *lower)
{
    for (size_t i = 0; lower[i]; i++) {
        if (tolower((unsigned char)text[i]) != lower[i]) return 0; /* ends at text's NUL */
    }
    return 1;
}

/* 1 if ``uri`` starts with "file:" in any case (FILE:, File:): schemes are
 * case-insensitive (RFC 3986, 3.1). */
static int file_scheme(const char *uri)
{
    return scheme_length(uri) == 4 && starts_in_any_case(uri, "file");
}

/* What uri_to_path found wrong. */
enum { URI_PATH, URI_TOO_LONG, URI_NUL, URI_SCHEME };

/* A file: URI (or a plain path) as a path (RFC 8089): %XX decoded (a % not followed by two
 * hexadecimal digits kept as it is), the host "localhost" in any case dropped
 * (file://localhost/x and file://LOCALHOST/x are /x), a drive letter where the host goes
 * taken for the drive (file://C:/x), another host kept as "//host/x" (a UNC path on
 * Windows), then made a local path (platform_local_path).
 * URI_PATH, or why not: URI_TOO_LONG when the path does not fit in ``n`` bytes (cut short,
 * it would be another folder), URI_NUL for a %00 (the path would end there, another
 * folder too), URI_SCHEME for another scheme than file: (http:, ...). */
static int uri_to_path(const char *uri, char *out, size_t n)
{
    const char *p = uri;
    int file = file_scheme(p);
    if (!file && scheme_length(p) > 1) return URI_SCHEME; /* one letter: a drive, C:/x */
    int authority = file && !strncmp(p + 4, "://", 3) && p[7] != '/'; /* file://host/... */
    if (file) p += strncmp(p + 4, "://", 3) ? 5 : 7;
    if (authority && starts_in_any_case(p, "localhost/")) { /* hosts: any case (3.2.2) */
        p += 9; /* from the slash on */
        authority = 0;
    } else if (authority && (p[0] | 0x20) >= 'a' && (p[0] | 0x20) <= 'z' && p[1] == ':' &&
               (p[2] == '/' || !p[2])) {
        authority = 0; /* file://C:/x, as some Windows tools write it: a drive, not a host */
    }
    size_t j = 0;
    if (authority && n > 3) {
        out[j++] = '/';
        out[j++] = '/';
    }
    for (; *p && j + 1 < n; p++) {
        int high = p[0] == '%' ? hex_digit(p[1]) : -1;
        int low = high >= 0 ? hex_digit(p[2]) : -1;
        if (low >= 0 && !high && !low) return URI_NUL;
        if (low >= 0) {
            out[j++] = (char)(high * 16 + low);
            p += 2;
        } else {
            out[j++] = *p;
        }
    }
    out[j] = '\0';
    if (*p) return URI_TOO_LONG;
    while (j > 1 && out[j - 1] == '/') out[--j] = '\0';
    platform_local_path(out, n);
    return URI_PATH;
}

/* Why the resource location cannot be read (into ``why``), or 0; the instance's path. */
static int location_refusal(Instance *c, fmi2String resources, char *why, size_t n)
{
    if (!resources || !resources[0]) return snprintf(why, n, "fmuResourceLocation is empty");
    size_t length = strlen(resources);
    int shown = (int)whole_characters(resources, length < 200 ? length : 200);
    const char *more = resources[shown] ? "..." : "";
    switch (uri_to_path(resources, c->resources, sizeof c->resources)) {
    case URI_TOO_LONG:
        return snprintf(why, n, "fmuResourceLocation %.*s... names a path longer than the "
                        "runtime's %d bytes", shown, resources, PATH_SIZE - 1);
    case URI_NUL:
        return snprintf(why, n, "fmuResourceLocation %.*s%s holds %%00, a NUL byte, which no "
                        "path can hold (the path would end there)", shown, resources, more);
    case URI_SCHEME:
        return snprintf(why, n, "fmuResourceLocation %.*s%s is not a file: URI (the FMU reads "
                        "its resources from a folder: file:///path/to/resources)", shown,
                        resources, more);
    default:
        return 0;
    }
}

/* Why this instantiation cannot go on (into ``why``), or 0; fills the instance's paths,
 * record and backend. */
static int instantiation_refusal(Instance *c, fmi2Type type, fmi2String guid,
                                 fmi2String resources, char *why, size_t n)
{
    char value[NAME_SIZE];
    const char *runtime = platform_getenv(RUNTIME_VARIABLE, value, sizeof value);
    long bad = not_utf8_at(c->name);
    if (bad >= 0) { /* Python cannot name the slave so; pythonfmu's binary crashed on it */
        return snprintf(why, n, "instanceName is not UTF-8 (byte %ld is 0x%02X): FMI 2.0 "
                        "strings are UTF-8", bad, (unsigned char)c->name[bad]);
    }
    if (!c->name[strspn(c->name, " \t\n\v\f\r")]) { /* every message would name no one */
        return snprintf(why, n, "instanceName is %s: FMI 2.0 asks for at least one "
                        "character that is not white space", c->name[0] ? "white space" : "empty");
    }
    if (type != fmi2CoSimulation) return snprintf(why, n, "the FMU supports co-simulation only");
    if (location_refusal(c, resources, why, n)) return 1;
    const char *record = read_record(c->resources, &c->record);
    if (record && record[0]) {
        return snprintf(why, n, "%s%s%s: %s is longer than the runtime holds", c->resources,
                        PATH_SEPARATOR, RECORD_FILE, record);
    }
    if (record) {
        return snprintf(why, n, "%s%s%s is missing or incomplete (not this FMU's extraction?)",
                        c->resources, PATH_SEPARATOR, RECORD_FILE);
    }
    if (!guid) return snprintf(why, n, "the GUID is NULL, expected %s", c->record.guid);
    if (strcmp(guid, c->record.guid)) {
        return snprintf(why, n,
                        "GUID %s is not this FMU's (%s): the host read another build's "
                        "modelDescription.xml",
                        guid, c->record.guid);
    }
    if (!read_variables(c, why, n)) return 1;
    if (!runtime || !runtime[0] || !strcmp(runtime, "native")) {
        c->backend = &python_backend;
    } else if (!strcmp(runtime, "pythonfmu")) {
        c->backend = &pythonfmu_backend;
    } else {
        return snprintf(why, n,
                        "%s=%s: expected \"pythonfmu\" (pythonfmu's own binary) or nothing (the "
                        "FMU's runtime)",
                        RUNTIME_VARIABLE, runtime);
    }
    return 0;
}

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn)
{
    char why[LINE_SIZE], line[LINE_SIZE + 64];
    if (runtime_gone()) return NULL; /* the process is shutting down: no message either */
    if (!name) {
        refuse_instantiation(functions, NULL, "fmi2Instantiate refused: instanceName is NULL");
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    size_t size = strlen(name) + 1;
    char *copy = c ? malloc(size) : NULL;
    if (!copy) {
        free(c);
        return NULL;
    }
    c->name = memcpy(copy, name, size);
    if (functions) c->host = *functions;
    c->stop = (double)INFINITY;
    c->logging = loggingOn;
    c->visible = visible;
    if (instantiation_refusal(c, type, guid, resources, why, sizeof why)) {
        cut_whole(why, sizeof why);
        snprintf(line, sizeof line, "fmi2Instantiate refused: %s", why);
        refuse_instantiation(functions, name, line);
    } else if (runtime_python(c) && c->backend->start(c)) {
        tell_debug(c, 0); /* loggingOn: every category */
        return c;
    }
    values_free_strings(&c->values);
    free(c->vars);
    free(c->name);
    free(c);
    return NULL;
}

static void free_states(Instance *c);

FMI2_EXPORT void fmi2FreeInstance(fmi2Component component)
{
    Instance *c = (Instance *)component;
    if (!c) return;
    free_states(c);
    c->backend->stop(c);
    values_free_strings(&c->values);
    free(c->vars);
    free(c->name);
    free(c);
}

FMI2_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

/* The place of ``name`` among the FMU's LogCategories (modelDescription.xml, from the
 * record), or -1. */
static int category_index(const Instance *c, const char *name)
{
    size_t length = strlen(name);
    int index = 0;
    for (const char *at = c->record.log_categories; *at; index++) {
        size_t n = strcspn(at, ",");
        if (n == length && !strncmp(at, name, n)) return index;
        at += n + (at[n] == ',');
    }
    return -1;
}

void debug_categories(const Instance *c, char *out, size_t size)
{
    size_t used = 0;
    int index = 0;
    out[0] = '\0';
    for (const char *at = c->record.log_categories; *at; index++) {
        size_t n = strcspn(at, ",");
        int on = c->logging || (index < 64 && (c->debugged >> index & 1));
        if (on && used + n + 2 <= size) {
            if (used) out[used++] = ',';
            memcpy(out + used, at, n);
            used += n;
            out[used] = '\0';
        }
        at += n + (at[n] == ',');
    }
}

/* The slave told which categories' debug messages pass, if anything is on or it was
 * told before (``told``); fmi2OK when there is nothing to tell. */
static fmi2Status tell_debug(Instance *c, int told)
{
    if (!told && !c->logging && !c->debugged) return fmi2OK;
    return c->backend->debug ? c->backend->debug(c) : fmi2OK;
}

/* FMI 2.0 (2.1.5): with categories, debug logging is on for those only. The runtime's
 * debug messages (fmi2OK ones) are of "logAll"; Warnings and worse reach the host whatever
 * is asked (the host needs to know why a call failed). A category the FMU does not
 * declare, or a NULL one, is refused with nothing changed, as the Reference FMUs do. */
FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn,
                                           size_t n, const fmi2String categories[])
{
    if (!component) return fmi2Error;
    Instance *c = (Instance *)component;
    c->logged = fmi2OK;
    NEED(categories, "category array", "fmi2SetDebugLogging");
    int all = n == 0;
    unsigned long long named = 0;
    for (size_t i = 0; i < n; i++) {
        if (!categories[i]) {
            return refuse(c, "fmi2SetDebugLogging refused: category %zu is NULL", i);
        }
        int index = category_index(c, categories[i]);
        if (index < 0) {
            size_t n_shown = 0; /* its first 64 bytes at most, whole characters */
            while (n_shown < 64 && categories[i][n_shown]) n_shown++;
            int shown = (int)whole_characters(categories[i], n_shown);
            return refuse(c, "fmi2SetDebugLogging refused: %.*s is not a log category of this "
                          "FMU (expected one of %s)", shown, categories[i],
                          c->record.log_categories);
        }
        all = all || !strcmp(categories[i], "logAll");
        if (index < 64) named |= 1ULL << index; /* past 64: with every category only */
    }
    c->logging = loggingOn && all;
    c->debugged = loggingOn ? named : 0;
    return tell_debug(c, 1);
}

/* ---- the call sequence -------------------------------------------------------------- */

#define INSTANCE(component)                       \
    Instance *c = (Instance *)(component);        \
    if (!c || python_gone()) return fmi2Error;    \
    c->logged = fmi2OK

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean hasTolerance,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean hasStop, fmi2Real stopTime)
{
    INSTANCE(component);
    char shown[40];
    if (c->phase != INSTANTIATED) {
        return refuse(c,
                      "setupExperiment refused: the FMU is %s (FMI 2.0 allows it only between "
                      "instantiation and initialisation)",
                      PHASES[c->phase]);
    }
    if (!isfinite(startTime)) {
        return refuse(c, "setupExperiment refused: startTime = %s s, expected a finite number",
                      show(startTime, shown));
    }
    if (hasStop && !(isfinite(stopTime) && stopTime >= startTime)) {
        char start[40];
        return refuse(c,
                      "setupExperiment refused: stopTime = %s s, expected a finite number >= "
                      "startTime (%s s)",
                      show(stopTime, shown), show(startTime, start));
    }
    fmi2Status s =
        answer(c, c->backend->setup(c, hasTolerance, tolerance, startTime, hasStop, stopTime));
    if (s == fmi2OK) {
        c->time = startTime;
        c->stop = hasStop ? stopTime : (double)INFINITY;
    }
    return s;
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component component)
{
    INSTANCE(component);
    if (c->phase != INSTANTIATED) {
        return refuse(c,
                      "enterInitializationMode refused: the FMU is %s (FMI 2.0 allows it once, "
                      "right after instantiation)",
                      PHASES[c->phase]);
    }
    fmi2Status s = answer(c, c->backend->enter(c));
    if (s == fmi2OK) c->phase = INITIALIZATION;
    return s;
}

FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component component)
{
    INSTANCE(component);
    if (c->phase != INITIALIZATION) {
        return refuse(c,
                      "exitInitializationMode refused: the FMU is %s, not in initialisation "
                      "mode (call enterInitializationMode first)",
                      PHASES[c->phase]);
    }
    fmi2Status s = answer(c, c->backend->exit(c));
    c->phase = s <= fmi2Warning ? INITIALIZED : FAILED;
    return s;
}

/* The step from ``at`` (formatted) of ``h`` s discarded, naming the first refused value
 * that stands (stand_refusal), with an Error line as the slave's own refusals. */
static fmi2Status discard_for_refusal(Instance *c, const char *at, double h)
{
    char why[512], shown[40], text[LINE_SIZE], escaped[2 * LINE_SIZE];
    fmi2ValueReference vr = 0;
    while (vr < c->count && !c->vars[vr].refused) vr++;
    const Variable *v = &c->vars[vr];
    write_refusal(c, vr, v->type, v->refused_value, 0, why, sizeof why);
    cut_whole(why, sizeof why);
    snprintf(text, sizeof text,
             "doStep at t = %s s, h = %s s refused: %s, so the step would use the value "
             "before it: write a valid value",
             at, show(h, shown), why);
    cut_whole(text, sizeof text);
    escape(text, escaped, sizeof escaped);
    instance_log(c, fmi2Error, "logStatusError", escaped);
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component component, fmi2Real t, fmi2Real h,
                                  fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    INSTANCE(component);
    char at[40], shown[40], now[40];
    show(t, at);
    if (c->phase != INITIALIZED) {
        return refuse(c, "doStep at t = %s s refused: the FMU is %s%s", at, PHASES[c->phase],
                      c->phase < INITIALIZED ? " (call exitInitializationMode first)" : "");
    }
    if (!(isfinite(h) && h > 0.0)) {
        return refuse(c,
                      "doStep at t = %s s refused: communication step %s s: expected a finite "
                      "number > 0",
                      at, show(h, shown));
    }
    double scale = c->time > 1.0 ? c->time : c->time < -1.0 ? -c->time : 1.0;
    double off = t > c->time ? t - c->time : c->time - t;
    if (!(isfinite(t) && off <= TIME_TOLERANCE * scale)) {
        return refuse(c,
                      "doStep at t = %s s refused: currentCommunicationPoint = %s s is not the "
                      "FMU's current time %s s (the start time or the end of the last step)",
                      at, at, show(c->time, now));
    }
    double end = t + h;
    if (!(isfinite(end) && end > t)) { /* the time would become inf, or not move */
        char ends[40];
        return refuse(c,
                      "doStep at t = %s s refused: communication step %s s: the step would end "
                      "at t + h = %s s, not a finite time after t",
                      at, show(h, shown), show(end, ends));
    }
    if (c->discarded && t == c->discarded_at[0] && h == c->discarded_at[1] &&
        c->writes == c->discarded_writes) {
        return refuse(c,
                      "doStep at t = %s s refused: this step was discarded just before and "
                      "nothing was set since, so it would be discarded again (the reason was "
                      "logged then); set other inputs, take a shorter step or stop",
                      at);
    }
    double stop_scale = c->stop > 1.0 ? c->stop : c->stop < -1.0 ? -c->stop : 1.0;
    if (t + h > c->stop + TIME_TOLERANCE * stop_scale) {
        return refuse(c,
                      "doStep at t = %s s refused: the step of %s s ends past the stop time "
                      "%s s given to setupExperiment (FMI 2.0: the FMU has to refuse it)",
                      at, show(h, shown), show(c->stop, now));
    }
    if (c->refusals) return discard_for_refusal(c, at, h);
    fmi2Status s = answer(c, c->backend->step(c, t, h, noSetFMUStatePriorToCurrentPoint));
    if (s <= fmi2Warning) c->time = t + h;
    /* a master may retry a discarded step shorter or with other inputs; the same step
     * again, nothing changed, is the loop some masters fall into (fmpy's simulate_fmu
     * retries it for ever when fmi2Terminated is false): refused above */
    c->discarded = s == fmi2Discard;
    c->discarded_at[0] = t;
    c->discarded_at[1] = h;
    c->discarded_writes = c->writes;
    return s;
}

FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component component)
{
    INSTANCE(component);
    if (c->phase != INITIALIZED) {
        return refuse(c,
                      "fmi2Terminate refused: the FMU is %s (FMI 2.0 allows it only once "
                      "initialised)",
                      PHASES[c->phase]);
    }
    fmi2Status s = answer(c, c->backend->terminate(c));
    if (c->phase != FAILED) c->phase = TERMINATED;
    return s;
}

FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component component)
{
    INSTANCE(component);
    fmi2Status s = answer(c, c->backend->reset(c));
    if (s <= fmi2Warning) {
        c->phase = INSTANTIATED;
        c->time = 0.0;
        c->stop = (double)INFINITY;
        c->discarded = 0;
        reset_values(c);
        tell_debug(c, 0); /* the new slave */
    }
    return s;
}

/* ---- values ------------------------------------------------------------------------- */

static fmi2Status get(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      void *values, const char *call)
{
    NEED(vr, "value-reference array", call);
    NEED(values, "value array", call);
    if (check_reads(c, vr, n, type) != fmi2OK) return fmi2Error;
    return n ? answer(c, c->backend->get(c, type, vr, n, values)) : fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[],
                                   size_t n, fmi2Real values[])
{
    INSTANCE(component);
    return get(c, 'R', vr, n, values, "fmi2GetReal");
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, fmi2Integer values[])
{
    INSTANCE(component);
    return get(c, 'I', vr, n, values, "fmi2GetInteger");
}

FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, fmi2Boolean values[])
{
    INSTANCE(component);
    return get(c, 'B', vr, n, values, "fmi2GetBoolean");
}

FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[],
                                     size_t n, fmi2String values[])
{
    INSTANCE(component);
    return get(c, 'S', vr, n, values, "fmi2GetString");
}

/* Whether writing ``x`` (NULL: strings, taken as a change) changes a value: a master
 * that writes the values a variable has changes nothing. fmpy's simulate_fmu writes its
 * inputs from a table before every try of a step, the same values before a retry. */
static int changes_values(const Instance *c, const fmi2ValueReference vr[], size_t n,
                          const double *x)
{
    if (!x) return 1;
    for (size_t i = 0; i < n; i++) {
        if (c->vars[vr[i]].value != x[i]) return 1;
    }
    return 0;
}

/* Check the values (as doubles: an Integer or Boolean fits), write them, remember them. */
static fmi2Status set(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                      const void *values, const double *x, const char *call)
{
    NEED(vr, "value-reference array", call);
    NEED(values, "value array", call);
    const fmi2String *strings = type == 'S' ? (const fmi2String *)values : NULL;
    if (check_writes(c, vr, n, type, x, strings) != fmi2OK) return fmi2Error;
    int changing = changes_values(c, vr, n, x);
    fmi2Status s = n ? answer(c, c->backend->set(c, type, vr, n, values)) : fmi2OK;
    if (s == fmi2OK && x) remember_writes(c, vr, n, x);
    if (s <= fmi2Warning && changing) c->writes++;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[],
                                   size_t n, const fmi2Real values[])
{
    INSTANCE(component);
    return set(c, 'R', vr, n, values, values, "fmi2SetReal");
}

/* An Integer's or Boolean's values as doubles for the checks (on the stack for the usual
 * few values). NULL arrays are refused first, then a count whose doubles would not fit in
 * size_t: malloc(n * 8) took it for a few bytes, and the copy wrote past them. */
static fmi2Status set_ints(Instance *c, char type, const fmi2ValueReference vr[], size_t n,
                           const int values[], const char *call)
{
    NEED(vr, "value-reference array", call);
    NEED(values, "value array", call);
    if (n > SIZE_MAX / sizeof(double)) {
        return refuse(c, "%s refused: n = %zu values, more than memory can hold", call, n);
    }
    double buffer[16], *x = n <= 16 ? buffer : malloc(n * sizeof(double));
    if (!x) return refuse(c, "%s refused: out of memory for %zu values", call, n);
    for (size_t i = 0; i < n; i++) x[i] = type == 'B' ? values[i] != 0 : values[i];
    fmi2Status s = set(c, type, vr, n, values, n ? x : NULL, call); /* as before for n = 0 */
    if (x != buffer) free(x);
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Integer values[])
{
    INSTANCE(component);
    return set_ints(c, 'I', vr, n, values, "fmi2SetInteger");
}

FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Boolean values[])
{
    INSTANCE(component);
    return set_ints(c, 'B', vr, n, values, "fmi2SetBoolean");
}

/* The host's Strings are copied before anything else reads them: a value may be a pointer
 * fmi2GetString returned (valid until this call), which the call itself would free before
 * reading it (the same variable written earlier in the call; pythonfmu's binary asked for
 * a fixed parameter's value to compare it with). */
FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[],
                                     size_t n, const fmi2String values[])
{
    INSTANCE(component);
    for (size_t i = 0; values && i < n; i++) {
        if (!values[i]) return refuse(c, "fmi2SetString refused: value %zu is NULL", i);
        if (!is_utf8((const unsigned char *)values[i])) {
            return refuse(c, "fmi2SetString refused: value %zu is not UTF-8", i);
        }
    }
    char **copies = values && n ? calloc(n, sizeof *copies) : NULL;
    size_t made = 0;
    for (; copies && made < n; made++) {
        size_t size = strlen(values[made]) + 1;
        if (!(copies[made] = malloc(size))) break;
        memcpy(copies[made], values[made], size);
    }
    fmi2Status s = values && n && made < n
                       ? refuse(c, "fmi2SetString refused: out of memory for %zu values", n)
                       : set(c, 'S', vr, n, copies ? (const void *)copies : values, NULL,
                             "fmi2SetString");
    for (size_t i = 0; i < made; i++) free(copies[i]);
    free(copies);
    return s;
}

/* ---- FMU state: the backend's, with the runtime's phase and time -------------------- */

/* Which FMU an instance is: the CRC-32 of its GUID. The three FMUs share this runtime and
 * its states' layout, so a state is checked against the FMU that took it too. */
static uint32_t fmu_of(const Instance *c)
{
    return crc32_of(0, c->record.guid, strlen(c->record.guid));
}

/* The magic a state serialised by ``backend`` starts with: the backends' states differ.
 * A value, not the backend's address, as each copy of this library has its own backends
 * and a state is set through any copy. */
static unsigned serial_magic(const Backend *backend)
{
    return backend == &pythonfmu_backend ? FORWARDED_MAGIC : SAVED_MAGIC;
}

/* The runtime whose states have ``magic``, as messages name it (RUNTIME_VARIABLE is read
 * as each instance is instantiated, so two instances in one process may run both). */
static const char *runtime_name(unsigned magic)
{
    return magic == FORWARDED_MAGIC ? "pythonfmu's runtime (" RUNTIME_VARIABLE "=pythonfmu)"
                                    : "the FMU's runtime";
}

/* ``state`` as a state this FMU took on ``c``'s backend (by any of its instances, through
 * any copy of this library), or NULL with ``call`` refused saying why. A host's pointer
 * is looked up among the states alive (python_states) before it is read: one that is no
 * state alive (freed already, another FMU's, the host's own memory, garbage) is refused
 * without being touched, where reading it would read freed or foreign memory, or crash;
 * one an instance on the other backend took holds that backend's kind of state, which
 * this backend would read as its own and crash. */
static Saved *saved_state(Instance *c, fmi2FMUstate state, const char *call)
{
    Saved *saved = state && python_states(STATE_ALIVE, state) ? (Saved *)state : NULL;
    if (!saved || saved->magic != SAVED_MAGIC || saved->fmu != fmu_of(c)) {
        refuse(c, "%s refused: not an FMU state of this FMU", call);
        return NULL;
    }
    if (saved->format != serial_magic(c->backend)) {
        refuse(c, "%s refused: a state taken on %s; this instance runs %s", call,
               runtime_name(saved->format), runtime_name(serial_magic(c->backend)));
        return NULL;
    }
    return saved;
}

/* Every instance's list of its states alive changes under Python's GIL: a state one
 * instance took may be freed through another instance of its FMU, in another thread or
 * through another copy of this library, and the GIL is the one lock every copy shares.
 * Once Python is gone no lock is taken (nothing but the exit frees instances then). */
static int hold_states(void) { return python_alive() ? py.GILState_Ensure() : -1; }

static void release_states(int gil)
{
    if (gil != -1) py.GILState_Release(gil);
}

/* ``saved`` among the states alive of ``owner``, which frees it with itself. */
static void own_state(Instance *owner, Saved *saved)
{
    int gil = hold_states();
    saved->owner = owner;
    saved->prev = NULL;
    saved->next = owner->states;
    if (saved->next) saved->next->prev = saved;
    owner->states = saved;
    release_states(gil);
}

/* ``saved`` off its owner's list (the caller holds the states' lock). */
static void unlink_state(Saved *saved)
{
    if (saved->prev) saved->prev->next = saved->next;
    if (saved->next) saved->next->prev = saved->prev;
    if (saved->owner->states == saved) saved->owner->states = saved->next;
}

/* ``saved`` forgotten by python_states and taken off its owner's list at once: 1 if it
 * was alive, and is now the caller's alone to free. */
static int forget_state(Saved *saved)
{
    int gil = hold_states();
    int forgotten = python_states(STATE_FORGET, saved);
    if (forgotten) unlink_state(saved);
    release_states(gil);
    return forgotten;
}

/* ``saved``, off every list, discarded by ``c`` and freed. */
static void free_saved(Instance *c, Saved *saved)
{
    if (!python_gone()) c->backend->discard(c, saved->inner); /* else gone with Python */
    saved->magic = 0;
    free(saved);
}

/* The states ``c`` took that the host did not free (FMI 2.0: fmi2FreeInstance frees all
 * the instance allocated): a host that saves states and never frees them keeps nothing.
 * Each is taken off the list under the states' lock, so that one freed meanwhile through
 * another instance is freed once. */
static void free_states(Instance *c)
{
    for (;;) {
        int gil = hold_states();
        Saved *saved = c->states;
        if (saved) {
            python_states(STATE_FORGET, saved);
            unlink_state(saved);
        }
        release_states(gil);
        if (!saved) return;
        free_saved(c, saved);
    }
}

/* ``saved`` holds ``inner``, the backend's state just taken, and ``c``'s phase and time. */
static void fill_saved(Instance *c, Saved *saved, void *inner)
{
    saved->magic = SAVED_MAGIC;
    saved->phase = c->phase;
    saved->time = c->time;
    saved->inner = inner;
    saved->fmu = fmu_of(c);
    saved->format = serial_magic(c->backend);
}

/* The backend saves first: a refused save allocates nothing. A state the host passes
 * (*state not NULL) is overwritten in place, as FMI 2.0 says. */
FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *state)
{
    INSTANCE(component);
    if (!state) return refuse(c, "fmi2GetFMUstate refused: not an FMU state of this FMU");
    Saved *old = NULL;
    if (*state && !(old = saved_state(c, *state, "fmi2GetFMUstate"))) return fmi2Error;
    void *inner = NULL;
    fmi2Status s = answer(c, c->backend->save(c, &inner));
    if (s > fmi2Warning) {
        if (inner) c->backend->discard(c, inner);
        return s;
    }
    if (old) {
        if (old->inner) c->backend->discard(c, old->inner);
        fill_saved(c, old, inner);
        return s;
    }
    Saved *saved = calloc(1, sizeof *saved);
    if (!saved || !python_states(STATE_KEEP, saved)) {
        c->backend->discard(c, inner);
        free(saved);
        return refuse(c, "fmi2GetFMUstate refused: out of memory");
    }
    fill_saved(c, saved, inner);
    own_state(c, saved);
    *state = saved;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate state)
{
    INSTANCE(component);
    Saved *saved = saved_state(c, state, "fmi2SetFMUstate");
    if (!saved) return fmi2Error;
    fmi2Status s = answer(c, c->backend->restore(c, saved->inner));
    c->writes++; /* a state set, restored or not, is a change the master made */
    if (s <= fmi2Warning) {
        c->phase = saved->phase;
        c->time = saved->time;
        clear_refusals(c); /* the state's values are in use, each valid */
        fmi2Status read = remember_state_values(c); /* the state is set: not undone */
        if (read == fmi2Fatal) c->phase = FAILED;
        if (read > s) s = read;
    }
    return s;
}

FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *state)
{
    INSTANCE(component);
    if (!state || !*state) return fmi2OK;
    Saved *saved = saved_state(c, *state, "fmi2FreeFMUstate");
    if (!saved) return fmi2Error;
    if (!forget_state(saved)) {
        return refuse(c, "fmi2FreeFMUstate refused: not an FMU state of this FMU");
    }
    free_saved(c, saved);
    *state = NULL;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate state,
                                                  size_t *size)
{
    INSTANCE(component);
    Saved *saved = saved_state(c, state, "fmi2SerializedFMUstateSize");
    if (!saved) return fmi2Error;
    if (!size) return refuse(c, "fmi2SerializedFMUstateSize refused: size is NULL");
    fmi2Status s = answer(c, c->backend->state_bytes(c, saved->inner, NULL, 0, size));
    if (s <= fmi2Warning) *size += SAVED_HEADER;
    return s;
}

FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate state,
                                             fmi2Byte bytes[], size_t size)
{
    INSTANCE(component);
    Saved *saved = saved_state(c, state, "fmi2SerializeFMUstate");
    if (!saved) return fmi2Error;
    if (!bytes || size < SAVED_HEADER) {
        return refuse(c, "fmi2SerializeFMUstate refused: %s",
                      bytes ? "the byte array is too small" : "the byte array is NULL");
    }
    size_t needed = 0;
    fmi2Status s = answer(c, c->backend->state_bytes(c, saved->inner, bytes + SAVED_HEADER,
                                                     size - SAVED_HEADER, &needed));
    if (s > fmi2Warning) return s;
    if (needed > size - SAVED_HEADER) {
        return refuse(c, "fmi2SerializeFMUstate refused: size = %zu bytes, the state needs %zu",
                      size, needed + SAVED_HEADER);
    }
    memcpy(bytes, &saved->format, sizeof(unsigned));
    memcpy(bytes + sizeof(unsigned), &saved->phase, sizeof(int));
    memcpy(bytes + sizeof(unsigned) + sizeof(int), &saved->time, sizeof(double));
    memcpy(bytes + SAVED_FMU, &saved->fmu, sizeof(uint32_t));
    uint32_t crc = state_crc(bytes, needed + SAVED_HEADER);
    memcpy(bytes + SAVED_CRC, &crc, sizeof crc);
    return s;
}

/* The host's ``state`` if it is a state alive of this FMU on ``c``'s backend, which
 * fmi2DeSerializeFMUstate then re-uses (fmpy's deSerializeFMUstate(bytes, state) hands one
 * in for re-use, as the Reference FMUs take it), else NULL: a new state is made. Looked up
 * among the states alive before it is read: any pointer may be handed in, and nothing else
 * is refused for it (FMI 2.0 asks for a new state there). */
static Saved *reusable(Instance *c, fmi2FMUstate state)
{
    Saved *saved = state && python_states(STATE_ALIVE, state) ? (Saved *)state : NULL;
    int ours = saved && saved->magic == SAVED_MAGIC && saved->fmu == fmu_of(c) &&
               saved->format == serial_magic(c->backend);
    return ours ? saved : NULL;
}

FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte bytes[],
                                               size_t size, fmi2FMUstate *state)
{
    INSTANCE(component);
    Saved header = {.magic = 0};
    if (!state) return refuse(c, "fmi2DeSerializeFMUstate refused: the state pointer is NULL");
    if (!bytes || size < SAVED_HEADER) {
        return refuse(c, "fmi2DeSerializeFMUstate refused: %s",
                      bytes ? "too few bytes for a state of this FMU" : "the byte array is NULL");
    }
    if (size > PTRDIFF_MAX) { /* no array is this long: the CRC would read past the bytes */
        return refuse(c, "fmi2DeSerializeFMUstate refused: size = %zu bytes, more than any "
                      "array holds (at most %zu)", size, (size_t)PTRDIFF_MAX);
    }
    memcpy(&header.magic, bytes, sizeof(unsigned));
    memcpy(&header.phase, bytes + sizeof(unsigned), sizeof(int));
    memcpy(&header.time, bytes + sizeof(unsigned) + sizeof(int), sizeof(double));
    memcpy(&header.fmu, bytes + SAVED_FMU, sizeof(uint32_t));
    if (header.magic != SAVED_MAGIC && header.magic != FORWARDED_MAGIC) {
        return refuse(c, "fmi2DeSerializeFMUstate refused: not a state of this FMU");
    }
    uint32_t crc;
    memcpy(&crc, bytes + SAVED_CRC, sizeof crc);
    if (crc != state_crc(bytes, size) || header.phase < INSTANTIATED || header.phase > FAILED ||
        !isfinite(header.time)) {
        return refuse(c, "fmi2DeSerializeFMUstate refused: these %zu bytes are not a state as "
                      "this FMU serialised it (their CRC-32 differs: changed, cut or extended "
                      "since)", size);
    }
    if (header.fmu != fmu_of(c)) { /* the backend alone may not tell the FMUs apart */
        return refuse(c, "fmi2DeSerializeFMUstate refused: a state of another FMU (its GUID "
                      "differs from this FMU's %s)", c->record.guid);
    }
    if (header.magic != serial_magic(c->backend)) { /* the backends' bytes differ */
        return refuse(c, "fmi2DeSerializeFMUstate refused: a state serialised on %s; this "
                      "instance runs %s",
                      runtime_name(header.magic), runtime_name(serial_magic(c->backend)));
    }
    header.format = header.magic;
    header.magic = SAVED_MAGIC;
    Saved *reused = reusable(c, *state);
    Saved *saved = reused ? NULL : calloc(1, sizeof *saved);
    if (!reused && !saved) return refuse(c, "fmi2DeSerializeFMUstate refused: out of memory");
    fmi2Status s = answer(c, c->backend->state_from_bytes(c, bytes + SAVED_HEADER,
                                                          size - SAVED_HEADER, &header.inner));
    if (s > fmi2Warning) {
        free(saved);
        return s;
    }
    if (reused) { /* in place, as fmi2GetFMUstate does: its owner keeps it */
        c->backend->discard(c, reused->inner);
        reused->inner = header.inner;
        reused->phase = header.phase;
        reused->time = header.time;
        return s;
    }
    if (!python_states(STATE_KEEP, saved)) {
        c->backend->discard(c, header.inner);
        free(saved);
        return refuse(c, "fmi2DeSerializeFMUstate refused: out of memory");
    }
    *saved = header;
    own_state(c, saved);
    *state = saved;
    return s;
}

/* ---- derivatives -------------------------------------------------------------------- */

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component component,
                                                   const fmi2ValueReference vr[], size_t n,
                                                   const fmi2Integer order[],
                                                   const fmi2Real values[])
{
    INSTANCE(component);
    const char *call = "fmi2SetRealInputDerivatives";
    char shown[40];
    NEED(vr, "value-reference array", call);
    NEED(order, "order array", call);
    NEED(values, "value array", call);
    if (!c->record.interpolates_inputs) {
        return refuse(c, "%s refused: this FMU takes no input derivatives "
                      "(canInterpolateInputs=\"false\")", call);
    }
    if (c->phase != INITIALIZATION && c->phase != INITIALIZED) {
        return refuse(c, "%s refused: the FMU is %s", call, PHASES[c->phase]);
    }
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(c, vr[i]);
        if (!v || v->type != 'R' || strcmp(v->causality, "input")) {
            return refuse(c, "%s refused: valueReference %u is not a Real input", call, vr[i]);
        }
        if (order[i] != 1 && order[i] != 2) {
            return refuse(c, "%s refused: %s: order %d, expected 1 or 2", call, v->name, order[i]);
        }
        if (!isfinite(values[i])) {
            return refuse(c, "%s refused: %s: derivative of order %d = %s, expected a finite "
                          "number", call, v->name, order[i], show(values[i], shown));
        }
    }
    fmi2Status s = n ? answer(c, c->backend->derivatives(c, vr, n, order, values)) : fmi2OK;
    if (s <= fmi2Warning) c->writes++;
    return s;
}

FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component,
                                                    const fmi2ValueReference vr[], size_t n,
                                                    const fmi2Integer order[], fmi2Real values[])
{
    (void)vr, (void)n, (void)order, (void)values;
    INSTANCE(component);
    return refuse(c, "fmi2GetRealOutputDerivatives refused: maxOutputDerivativeOrder is 0");
}

FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component component,
                                                    const fmi2ValueReference u[], size_t nu,
                                                    const fmi2ValueReference z[], size_t nz,
                                                    const fmi2Real dv[], fmi2Real dz[])
{
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    INSTANCE(component);
    return refuse(c, "fmi2GetDirectionalDerivative refused: the FMU provides no directional "
                     "derivatives");
}

/* ---- status: answered here, the same with either backend ---------------------------- */

FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component component)
{
    INSTANCE(component);
    return refuse(c, "fmi2CancelStep refused: doStep never returns fmi2Pending");
}

FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind kind,
                                     fmi2Status *value)
{
    (void)kind, (void)value;
    INSTANCE(component);
    instance_log(c, fmi2Discard, "logStatusDiscard",
                 "fmi2GetStatus: no step is pending (doStep never returns fmi2Pending)");
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind kind,
                                         fmi2Real *value)
{
    INSTANCE(component);
    if (!value) return refuse(c, "fmi2GetRealStatus refused: value is NULL");
    if (kind != fmi2LastSuccessfulTime) {
        return refuse(c, "fmi2GetRealStatus refused: kind %d, expected fmi2LastSuccessfulTime",
                      (int)kind);
    }
    *value = c->time;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind kind,
                                            fmi2Integer *value)
{
    (void)kind, (void)value;
    INSTANCE(component);
    return refuse(c, "fmi2GetIntegerStatus refused: FMI 2.0 defines no Integer status");
}

FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind kind,
                                            fmi2Boolean *value)
{
    INSTANCE(component);
    if (!value) return refuse(c, "fmi2GetBooleanStatus refused: value is NULL");
    if (kind != fmi2Terminated) {
        return refuse(c, "fmi2GetBooleanStatus refused: kind %d, expected fmi2Terminated",
                      (int)kind);
    }
    *value = fmi2False; /* the slaves never end a simulation themselves */
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind kind,
                                           fmi2String *value)
{
    (void)kind, (void)value;
    INSTANCE(component);
    return refuse(c, "fmi2GetStringStatus refused: no step is pending");
}
