/* Load on glibc 2.17 (CentOS 7, manylinux2014) whatever glibc the runtime is built on.
 *
 * A library built with `cc` binds each glibc function to its default version on the build
 * machine: glibc 2.34 moved dlopen & co. into libc.so.6 with version GLIBC_2.34, which no
 * older glibc defines, so the library would not load there. The directives below bind
 * those references to the versions every x86-64 glibc since 2.2.5 has (in libdl.so.2
 * before 2.34, which the build links by file name for that reason); every other function
 * the runtime uses already has a default version <= 2.17 (a test reads `objdump -T`).
 * `zig cc -target x86_64-linux-gnu.2.17` picks the same versions by itself: it defines
 * AUV_GLIBC_TARGET.
 */
#ifndef AUV_FMU_GLIBC_FLOOR_H
#define AUV_FMU_GLIBC_FLOOR_H

#if defined(__linux__) && defined(__x86_64__) && !defined(AUV_GLIBC_TARGET)
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
__asm__(".symver dlclose,dlclose@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
#endif

#endif
