/* A C host that hands our FMUs the odd arguments FMI 2.0 forbids or leaves to the FMU to
 * judge, at fmi2Instantiate and fmi2SetDebugLogging:
 *
 *   odd_arguments DIR ID
 *
 * an instance name that is empty or only white space; a resource location with %00 in it
 * (a NUL byte no path can hold), of another scheme than file:, with its scheme in capital
 * letters, and with bytes that are not UTF-8 (%FF decoded, and a raw 0xFF); a GUID that is
 * not UTF-8; a log category that is not UTF-8. Prints "<case> NULL" or "<case> instance"
 * for fmi2Instantiate, "<case> <status>" for the other calls, and "log [S] {CATEGORY} TEXT"
 * for each message. Every message is checked as the log contract asks (UTF-8 and strictly
 * so: no overlong form, no surrogate; a declared category; a printf format without a
 * conversion); one that breaks it prints "VIOLATION: ..." and is not formatted.
 */
#define _GNU_SOURCE /* strdup */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_callbacks.h"
#include "log_rules.h"

typedef void *Component;

static struct {
    Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
    void (*free_instance)(Component);
    int (*debug)(Component, int, size_t, const char *const *);
} F;
static char description[65536], guid[128], dir[4096];

/* The length of the UTF-8 character at ``p`` as Python's strict decoder takes it (no
 * overlong form, no surrogate, nothing above U+10FFFF), or 0. */
static int character(const unsigned char *p)
{
    int n = p[0] < 0x80 ? 1 : p[0] >= 0xC2 && p[0] < 0xE0 ? 2 : p[0] >= 0xE0 && p[0] < 0xF0 ? 3
          : p[0] >= 0xF0 && p[0] < 0xF5 ? 4 : 0;
    unsigned long code = n == 1 ? p[0] : p[0] & (0x7F >> n);
    for (int k = 1; k < n; k++) {
        if ((p[k] & 0xC0) != 0x80) return 0;
        code = code << 6 | (p[k] & 0x3F);
    }
    if ((n == 3 && (code < 0x800 || (code >= 0xD800 && code <= 0xDFFF))) ||
        (n == 4 && (code < 0x10000 || code > 0x10FFFF))) {
        return 0;
    }
    return n;
}

static int is_utf8(const char *text)
{
    for (const unsigned char *p = (const unsigned char *)text; *p;) {
        int n = character(p);
        if (!n) return 0;
        p += n;
    }
    return 1;
}

static void logger(void *env, const char *name, int status, const char *category,
                   const char *message, ...)
{
    (void)env, (void)name;
    const char *broken = !message || !is_utf8(message) ? "a message that is not UTF-8"
                         : !category || !declared_in(description, category)
                             ? "an undeclared category"
                         : !no_conversion(message) ? "a printf conversion"
                                                   : NULL;
    if (broken) {
        printf("VIOLATION: %s (status %d)\n", broken, status);
        return;
    }
    va_list args;
    va_start(args, message);
    print_message(status, category, message, args);
    va_end(args);
}

static const Callbacks callbacks = {logger, calloc, free, NULL, NULL};

static void load(const char *id)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        printf("dlopen failed: %s\n", dlerror());
        exit(2);
    }
    *(void **)&F.instantiate = need(library, "fmi2Instantiate");
    *(void **)&F.free_instance = need(library, "fmi2FreeInstance");
    *(void **)&F.debug = need(library, "fmi2SetDebugLogging");
    read_description(dir, description, sizeof description, guid);
}

/* fmi2Instantiate with these arguments, each in a heap block of its own size (ASan then
 * sees a read past its end): prints "<case> NULL" or "<case> instance"; the instance is
 * returned (NULL if none). */
static Component instantiate(const char *label, const char *name, const char *id,
                             const char *uri)
{
    char *copies[] = {strdup(name), strdup(id), strdup(uri)};
    Component c = F.instantiate(copies[0], 1, copies[1], copies[2], &callbacks, 0, 0);
    for (int i = 0; i < 3; i++) free(copies[i]);
    printf("%s %s\n", label, c ? "instance" : "NULL");
    return c;
}

static void instantiations(void)
{
    char uri[4400], resources[4300];
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    const char *names[][2] = {{"name-empty", ""}, {"name-blank", " \t "}};
    for (int i = 0; i < 2; i++) {
        Component c = instantiate(names[i][0], names[i][1], guid, resources);
        if (c) F.free_instance(c);
    }
    const char *uris[][2] = {
        {"uri-nul", "file://%s/resources%%00/../elsewhere"},
        {"uri-http", "http://localhost%s/resources"},
        {"uri-not-utf8-escaped", "file://%s/resources/%%FF"},
        {"uri-not-utf8-raw", "file://%s/resources/\xff"},
        {"uri-capital-scheme", "FILE://%s/resources"},
    };
    for (int i = 0; i < 5; i++) {
        snprintf(uri, sizeof uri, uris[i][1], dir);
        Component c = instantiate(uris[i][0], "odd", guid, uri);
        if (c) F.free_instance(c);
    }
    Component c = instantiate("guid-not-utf8", "odd", "\xff{not a guid}", resources);
    if (c) F.free_instance(c);
    /* a GUID of UTF-8 the message cuts short inside a character ("x" then 2-byte ones) */
    char long_guid[2 + 2 * 1200] = "x";
    for (int i = 0; i < 1200; i++) strcat(long_guid + 2 * i, "\xc3\xa9");
    c = instantiate("guid-long-utf8", "odd", long_guid, resources);
    if (c) F.free_instance(c);
}

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    if (argc != 3) {
        fprintf(stderr, "usage: odd_arguments DIR ID\n");
        return 2;
    }
    snprintf(dir, sizeof dir, "%s", argv[1]);
    load(argv[2]);
    instantiations();
    char resources[4300];
    snprintf(resources, sizeof resources, "file://%s/resources", dir);
    Component c = instantiate("instance", "odd", guid, resources);
    if (!c) return 3;
    const char *categories[] = {"log\xff\xfeSteps"};
    printf("category-not-utf8 %d\n", F.debug(c, 1, 1, categories));
    F.free_instance(c);
    return 0;
}
