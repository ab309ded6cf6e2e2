/* Finding and starting the Python an FMU runs its model in (python_start.c). */
#ifndef DELTAFMI_PYTHON_START_H
#define DELTAFMI_PYTHON_START_H

#include <stddef.h>

/* Find or start the interpreter for the FMU whose resources directory is `resources` and start the
 * bridge in it. Call once per FMU binary, under the process-wide start-up lock (process_lock.h).
 * 0, or -1 with one message in error. */
int dfmi_start_python(const char *resources, char *error, size_t size);

#endif
