/* The FMI 2.0 plumbing shared by the third-party-style test FMUs (in the style of the FMI
 * Reference FMUs): plumbing.c implements every fmi2 function of Model Exchange and
 * Co-Simulation once, with a small state machine; each model (one model.c) implements the
 * functions declared at the end of this file and nothing else.
 *
 * Co-Simulation: fmi2DoStep advances the model with its own advance() (an exact solution or
 * an explicit method), stopping at time events (nextEventTime) and state events (advance()
 * says so) and running the event iteration there. When the model sets terminateSimulation,
 * fmi2DoStep returns fmi2Discard at the time reached, and fmi2GetBooleanStatus(fmi2Terminated)
 * and fmi2GetRealStatus(fmi2LastSuccessfulTime) tell the importer so. A step longer than
 * maxStepSize (when a model sets it) is discarded without terminating: the importer must retry
 * with a shorter step or give up.
 */
#ifndef PLUMBING_H
#define PLUMBING_H

#include <stdbool.h>
#include <stddef.h>

#include "fmi2Functions.h"

/* Longest String value (including the terminating zero) a model stores. */
#define STRING_SIZE 256

typedef enum {
    Instantiated,
    InitializationMode,
    EventMode,           /* ME */
    ContinuousTimeMode,  /* ME */
    StepComplete,        /* CS */
    StepFailed,          /* CS: fmi2DoStep returned fmi2Discard (the model terminated) */
    Terminated,
    ErrorState
} ModelState;

typedef struct ModelData ModelData;  /* defined by each model; plain data (memcpy makes a snapshot) */

typedef struct {
    fmi2Type type;
    ModelState state;
    char *instanceName;
    char resourceDir[4096];  /* fmuResourceLocation as a path, ending in '/' ("" if none) */
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment environment;
    bool loggingOn;  /* logInfo() is silent unless the importer turned debug logging on */
    double startTime;
    double time;
    double maxStepSize;  /* CS: fmi2DoStep discards longer steps (not terminating); 0: any step */
    /* the event iteration's results: eventUpdate() sets them */
    bool newDiscreteStatesNeeded;
    bool terminateSimulation;
    bool valuesOfContinuousStatesChanged;
    bool nextEventTimeDefined;
    double nextEventTime;
    ModelData *data;
} ModelInstance;

/* When a variable may be set (FMI 2.0, section 3.2.3 and 4.2.4). */
typedef enum { Fixed, Tunable, ContinuousInput, DiscreteInput } Settable;

/* fmi2OK when the variable `name` of kind `kind` may be set now, else logs and returns fmi2Error. */
fmi2Status checkSettable(ModelInstance *comp, const char *name, Settable kind);

/* Copies value into a STRING_SIZE buffer; fmi2Error (logged) when it does not fit. */
fmi2Status copyString(ModelInstance *comp, char *target, fmi2String value);

void logError(ModelInstance *comp, const char *format, ...);
void logInfo(ModelInstance *comp, const char *format, ...);  /* only with debug logging on */

/* A time event is due at the current time (nextEventTime reached, up to round-off). */
bool timeEventDue(const ModelInstance *comp);

/* --- what a model implements ------------------------------------------------------------ */

extern const char *const MODEL_GUID;
extern const size_t MODEL_DATA_SIZE;            /* sizeof(ModelData) */
extern const size_t NUMBER_OF_STATES;
extern const size_t NUMBER_OF_EVENT_INDICATORS;

void setStartValues(ModelInstance *comp);
/* At fmi2ExitInitializationMode: compute what the parameters define, set the first time event. */
fmi2Status initialize(ModelInstance *comp);

fmi2Status getReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real *value);
fmi2Status setReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real value);
fmi2Status getInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer *value);
fmi2Status setInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer value);
fmi2Status getBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean *value);
fmi2Status setBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean value);
fmi2Status getString(ModelInstance *comp, fmi2ValueReference vr, fmi2String *value);
fmi2Status setString(ModelInstance *comp, fmi2ValueReference vr, fmi2String value);

void getContinuousStates(ModelInstance *comp, double x[]);
void setContinuousStates(ModelInstance *comp, const double x[]);
void getDerivatives(ModelInstance *comp, double dx[]);
void getEventIndicators(ModelInstance *comp, double z[]);

/* One round of the event iteration at comp->time (the flags are reset before each round). */
void eventUpdate(ModelInstance *comp);

/* Co-Simulation: integrate from comp->time towards t_stop, set comp->time to the time reached
 * and return true when the model stopped early at a state event. */
bool advance(ModelInstance *comp, double t_stop);

#endif
