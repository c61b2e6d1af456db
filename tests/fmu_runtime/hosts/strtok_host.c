/* A host that reads the instances to make from one argument with strtok, as a C program
 * parsing its command line does, and instantiates each inside that loop:
 *
 *   strtok_host LIBRARY RESOURCE_URI GUID NAME,NAME,...
 *
 * prints "made NAME" (or "NULL NAME") for each, then "instances: N", and frees them. The
 * FMU's runtime has to leave strtok's hidden state alone: the first instance in a process
 * without Python probes a Python, whose answer the runtime once split with strtok, and the
 * host's next strtok(NULL, ...) then read the runtime's freed buffer; on Windows, its
 * search of PATH for python.exe split PATH with strtok.
 */
#include <stdio.h>
#include <string.h>
#ifdef _WIN32 /* compiled for win64 too (tests/fmu_runtime/test_win64_runtime.py, Wine) */
#include <windows.h>
#define dlopen(path, flags) ((void *)LoadLibraryA(path))
#define dlsym(library, name) ((void *)GetProcAddress((HMODULE)(library), name))
#else
#include <dlfcn.h>
#endif

#include "fmi2_callbacks.h"
typedef void *(*Instantiate)(const char *, int, const char *, const char *, const Callbacks *,
                             int, int);
typedef void (*FreeInstance)(void *);

int main(int argc, char **argv)
{
    if (argc != 5) {
        fprintf(stderr, "usage: strtok_host LIBRARY RESOURCE_URI GUID NAME,NAME,...\n");
        return 2;
    }
    void *library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    Instantiate instantiate = NULL;
    FreeInstance free_instance = NULL;
    if (library) {
        *(void **)&instantiate = dlsym(library, "fmi2Instantiate");
        *(void **)&free_instance = dlsym(library, "fmi2FreeInstance");
    }
    if (!instantiate || !free_instance) {
        fprintf(stderr, "cannot load %s\n", argv[1]);
        return 2;
    }
    Callbacks callbacks = {NULL, NULL, NULL, NULL, NULL};
    void *made[16];
    int n = 0;
    for (char *name = strtok(argv[4], ","); name && n < 16; name = strtok(NULL, ",")) {
        made[n] = instantiate(name, 1, argv[3], argv[2], &callbacks, 0, 0);
        printf("%s %s\n", made[n] ? "made" : "NULL", name);
        fflush(stdout);
        if (made[n]) n++;
    }
    printf("instances: %d\n", n);
    for (int i = 0; i < n; i++) free_instance(made[i]);
    return 0;
}
