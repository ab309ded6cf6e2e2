/* The process-wide start-up lock of deltafmi FMU binaries.
 *
 * Each FMU's binary is a separate copy (binaries/linux64/<id>.so of each unpacked FMU) with its own
 * static variables, so a pthread mutex cannot be shared between two FMUs, let alone between FMUs
 * built by different deltafmi versions. What every binary in the process can find is a name in the
 * kernel's abstract AF_UNIX namespace: the lock is held by whoever has bound the socket name
 *
 *     "\0deltafmi-start-v1-<pid>"          (this exact spelling is the protocol: never change it;
 *                                           a new protocol takes a new name, "v2")
 *
 * bind() succeeding is taking the lock, closing the socket is releasing it, EADDRINUSE means
 * another thread holds it. An abstract name is no file: it vanishes with the last descriptor, so
 * nothing goes stale, and a process that dies holding it releases it. The descriptor is
 * close-on-exec, so a child started meanwhile does not keep it. Two processes whose pids look equal
 * (different pid namespaces sharing one network namespace) would only take turns, never deadlock.
 * The lock is short-lived (only the check for a running interpreter and its start), so waiters
 * poll with a sleep that grows from 50 us to 2 ms rather than block. */
#define _GNU_SOURCE
#include "glibc_floor.h"
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "process_lock.h"

int dfmi_process_lock(double timeout_s, char *error, size_t size) {
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    struct sockaddr_un address;
    memset(&address, 0, sizeof address);
    address.sun_family = AF_UNIX;
    /* sun_path[0] stays 0: the abstract namespace; the name's length is part of it (no final 0) */
    int n = snprintf(address.sun_path + 1, sizeof address.sun_path - 1, "deltafmi-start-v1-%ld", (long)getpid());
    socklen_t length = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + 1 + (size_t)n);
    long pause_ns = 50000;
    double waited = 0.0;
    for (;;) {
        if (bind(fd, (struct sockaddr *)&address, length) == 0) return fd;
        if (errno != EADDRINUSE) { /* sockets forbidden here: the per-binary lock is all there is */
            close(fd);
            return -1;
        }
        if (waited >= timeout_s) {
            close(fd);
            snprintf(error, size, "fmi2Instantiate: another FMU in this process has been starting Python for "
                     "%.0f s and still holds the start-up lock (abstract socket '@deltafmi-start-v1-%ld')",
                     waited, (long)getpid());
            return DFMI_PROCESS_LOCK_TIMEOUT;
        }
        struct timespec pause = {0, pause_ns};
        while (nanosleep(&pause, &pause) != 0 && errno == EINTR) {
        }
        waited += pause_ns * 1e-9;
        pause_ns = pause_ns < 1000000 ? 2 * pause_ns : 2000000;
    }
}

void dfmi_process_unlock(int handle) {
    if (handle >= 0) close(handle);
}
