/* A library that, preloaded into a host (LD_PRELOAD), makes posix_spawn's file actions fail
 * as when memory runs out (posix_spawn_file_actions_adddup2 returns ENOMEM, nothing added):
 * a child spawned regardless would write to the host's own stdout and stderr.
 */
#include <errno.h>
#include <spawn.h>

int posix_spawn_file_actions_adddup2(posix_spawn_file_actions_t *actions, int fd, int to)
{
    (void)actions, (void)fd, (void)to;
    return ENOMEM;
}
