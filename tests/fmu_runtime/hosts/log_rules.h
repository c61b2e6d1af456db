/* Two rules of the log contract the test hosts check in every message an FMU hands their
 * logger: its category is declared in the model description, and it is a printf format
 * that reads no argument. */
#ifndef LOG_RULES_H
#define LOG_RULES_H

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* 1 if ``category`` is a <Category name="..."> of the model description ``description``. */
static inline int declared_in(const char *description, const char *category)
{
    const char *start = strstr(description, "<LogCategories>");
    const char *end = start ? strstr(start, "</LogCategories>") : NULL;
    char attribute[300];
    snprintf(attribute, sizeof attribute, "name=\"%s\"", category);
    const char *at = start ? strstr(start, attribute) : NULL;
    return at && at < end;
}

/* 1 if every % of ``message`` is doubled: a format that reads no argument. */
static inline int no_conversion(const char *message)
{
    for (const char *p = message; *p; p++) {
        if (*p == '%' && *++p != '%') return 0;
    }
    return 1;
}

/* Print a message that keeps the rules as "log [STATUS] {CATEGORY} TEXT", formatted with
 * its ``args`` (none: every % doubled). */
static inline void print_message(int status, const char *category, const char *message,
                                 va_list args)
{
    char text[8192];
    vsnprintf(text, sizeof text, message, args);
    printf("log [%d] {%s} %s\n", status, category, text);
}

#endif
