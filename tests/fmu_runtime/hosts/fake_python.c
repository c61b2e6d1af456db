/* A stand-in for python.exe that answers the runtime's probe as Python 3.8 would (3.8.1,
 * or 3.8.2 when started as the launcher's "py -3"), once it has checked that the probe's
 * arguments arrived as sent (its script, with its newlines and quotes, as one argument)
 * and that PYTHONHOME was left out of its environment; else it exits with status 3 or 4.
 * For tests/fmu_runtime/test_win64_runtime.py, which runs the runtime under Wine.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
int main(int argc, char **argv)
{
    int micro = 1, i = 1;
    if (argc > i && !strcmp(argv[i], "-3")) {
        micro = 2;
        i++;
    }
    if (argc != i + 2 || strcmp(argv[i], "-c") || strncmp(argv[i + 1], "import sys\n", 11) ||
        !strstr(argv[i + 1], "w('end', 'yes')\n")) {
        fprintf(stderr, "arguments not as sent\n");
        return 3;
    }
    if (getenv("PYTHONHOME")) {
        fprintf(stderr, "PYTHONHOME reached the probe\n");
        return 4;
    }
    printf("version=3.8.%d\n", micro);
    return 0;
}
