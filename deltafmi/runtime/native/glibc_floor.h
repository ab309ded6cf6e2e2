/* The FMU binary binds the oldest versions of the few glibc functions whose default version is
 * recent (dlopen and friends moved into libc in glibc 2.34; memcpy got a new version in 2.14), so it
 * loads on old Linux systems too (and a wheel's prebuilt copy passes as manylinux2014). A portable FMU's bundled binaries need a newer glibc (the builder's
 * floor, recorded in python.cfg), and the loader must be able to run to say so instead of the host
 * failing to dlopen the FMU with a bare "version `GLIBC_2.34' not found". Include first, in every
 * source of the binary (each object binds its own references). */
#ifndef DELTAFMI_GLIBC_FLOOR_H
#define DELTAFMI_GLIBC_FLOOR_H
#if defined(__x86_64__) && defined(__GLIBC__) || defined(__x86_64__) && defined(__linux__)
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
__asm__(".symver memcpy,memcpy@GLIBC_2.2.5");
/* libm's pow, exp and log got new versions in 2.29 (the same functions; only their errno
 * reporting differs): the Co-Simulation step calls pow as the kernels do (-fno-builtin-pow) */
__asm__(".symver pow,pow@GLIBC_2.2.5");
__asm__(".symver exp,exp@GLIBC_2.2.5");
__asm__(".symver log,log@GLIBC_2.2.5");
#endif
#endif
