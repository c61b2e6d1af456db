/* A minimal win64 FMI host for the runtime's Windows build, run under Wine by
 * tests/fmu_runtime/test_win64_runtime.py: loads DLL with LoadLibraryW, calls
 * fmi2Instantiate with the resource URI and GUID given, prints every log line and whether
 * an instance was made. Usage: win64_host DLL RESOURCE_URI GUID
 */
#include <windows.h>
#include <stdarg.h>
#include <stdio.h>
typedef void *(*Instantiate)(const char *, int, const char *, const char *, const void *, int, int);
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
static void logger(void *env, const char *name, int status, const char *category, const char *message, ...)
{
    (void)env, (void)name;
    printf("LOG %d %s: %s\n", status, category ? category : "(null)", message);
}
int wmain(int argc, wchar_t **argv)
{
    if (argc < 4) return 2;
    HMODULE dll = LoadLibraryW(argv[1]);
    if (!dll) {
        printf("LoadLibrary failed %lu\n", GetLastError());
        return 1;
    }
    Instantiate instantiate = (Instantiate)(void *)GetProcAddress(dll, "fmi2Instantiate");
    char uri[4096], guid[128];
    WideCharToMultiByte(CP_UTF8, 0, argv[2], -1, uri, sizeof uri, NULL, NULL);
    WideCharToMultiByte(CP_UTF8, 0, argv[3], -1, guid, sizeof guid, NULL, NULL);
    struct {
        Logger logger;
        void *allocate, *free, *step_finished, *environment;
    } callbacks = {logger, NULL, NULL, NULL, NULL}; /* fmi2CallbackFunctions */
    void *c = instantiate("inst", 1 /* fmi2CoSimulation */, guid, uri, &callbacks, 0, 1);
    printf("instance %s\n", c ? "made" : "NULL");
    fflush(stdout);
    return 0;
}
