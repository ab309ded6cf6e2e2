/* A Co-Simulation step of a component with states and compiled kernels, taken in C (cs_step.c). */
#ifndef DELTAFMI_CS_STEP_H
#define DELTAFMI_CS_STEP_H

#include "core.h"

/* Whether the C layer takes this step (the component shares a DfmiCs and its kernels hold its
 * attributes now); otherwise the Python instance takes it. */
int dfmi_cs_takes_step(const Instance *c);
/* FmuInstance.do_step's step from t over h in C: CVODE from the shared solver, the kernels for
 * what a step evaluates, Python only for the solver's creation, the model's event iteration and
 * failures. `events` as core.h's DfmiStepEvents says, reporting through the control array as
 * documented there. Returns an FMI status (DFMI_DISCARD: the component ended the simulation). */
int dfmi_cs_step(Instance *c, double t, double h, DfmiStepEvents events);

#endif
