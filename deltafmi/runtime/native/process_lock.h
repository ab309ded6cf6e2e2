/* One start-up lock per process, shared by every deltafmi FMU binary in it (process_lock.c). */
#ifndef DELTAFMI_PROCESS_LOCK_H
#define DELTAFMI_PROCESS_LOCK_H

#include <stddef.h>

/* The lock could not be had in time; the message is in `error`. */
#define DFMI_PROCESS_LOCK_TIMEOUT (-2)

/* Wait for the process-wide start-up lock. Returns a handle >= 0 to pass to dfmi_process_unlock;
 * -1 when this process cannot make one (no AF_UNIX sockets: the caller goes on with its own
 * per-binary lock); DFMI_PROCESS_LOCK_TIMEOUT after `timeout_s` seconds, with a message. */
int dfmi_process_lock(double timeout_s, char *error, size_t size);

/* Release a lock from dfmi_process_lock (any handle, -1 included). */
void dfmi_process_unlock(int handle);

#endif
