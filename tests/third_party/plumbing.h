/* The plumbing shared by the third-party-style test FMUs (in the style of the FMI Reference
 * FMUs), for FMI 2.0 and FMI 3.0 alike. Each model (one model.c) implements the functions
 * declared under "what a model implements" and nothing else; it knows no FMI version:
 *
 *   common.c      what both versions share: the instance, logging, the event iteration, the
 *                 Co-Simulation step loop with events, FMU state snapshots
 *   plumbing.c    every fmi2 function of Model Exchange and Co-Simulation
 *   plumbing3.c   every fmi3 function (Model Exchange and Co-Simulation; Scheduled Execution
 *                 is not offered)
 *   shared/       physics an FMI 2.0 and an FMI 3.0 model share (the bouncing ball, the table)
 *
 * Variable values: an FMI 2.0 model answers getReal/getInteger/getBoolean/getString (and the
 * setters) per value reference; an FMI 3.0 model lists its variables in VARIABLES (type, element
 * count, where its value lives in ModelData, when it may be set) and the plumbing reads and writes
 * them, arrays included, with calculateValues() bringing calculated values up to date first.
 *
 * Co-Simulation: the step advances the model with its own advance() (an exact solution or an
 * explicit method), stopping at time events (nextEventTime) and state events (advance() says so)
 * and running the event iteration there, or (FMI 3.0 with event mode and early return) returning
 * at the event for the importer to handle it in Event Mode. A model that sets terminateSimulation
 * ends the step at that time: fmi2DoStep returns fmi2Discard with fmi2Terminated, fmi3DoStep
 * returns terminateSimulation with lastSuccessfulTime. A step longer than maxStepSize (when a
 * model sets it) is discarded without terminating: the importer must retry with a shorter step.
 */
#ifndef PLUMBING_H
#define PLUMBING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Numbered as fmi2Status and fmi3Status. */
typedef enum { OK, Warning, Discard, Error, Fatal } Status;

typedef unsigned int ValueReference;

typedef enum { ModelExchange, CoSimulation } InterfaceType;

/* Longest String value (including the terminating zero) and longest Binary value a model stores. */
#define STRING_SIZE 256
#define BINARY_SIZE 256

typedef struct {
    size_t size;
    unsigned char bytes[BINARY_SIZE];
} BinaryValue;

typedef enum {
    Instantiated,
    InitializationMode,
    EventMode,           /* ME, and FMI 3.0 CS with eventModeUsed */
    ContinuousTimeMode,  /* ME */
    StepMode,            /* CS (FMI 2.0: "step complete") */
    StepDiscarded,       /* CS: the last step returned Discard */
    Terminated,
    ErrorState
} ModelState;

typedef struct ModelData ModelData;  /* defined by each model; plain data (memcpy makes a snapshot) */
typedef struct ModelInstance ModelInstance;

/* How the FMI version's front end passes a message to the importer's logger. */
typedef void (*LogFunction)(ModelInstance *comp, Status status, const char *category, const char *message);

struct ModelInstance {
    InterfaceType type;
    ModelState state;
    char *instanceName;
    char resourceDir[4096];  /* the FMU's resources folder as a path ending in '/' ("" if none) */
    LogFunction log;
    void (*logger)(void);    /* the importer's callback, called by `log` with its real type */
    void *environment;
    bool loggingOn;          /* logInfo() is silent unless the importer turned debug logging on */
    unsigned categories;     /* FMI 3.0: the log categories enabled (bits in the order of LOG_CATEGORIES) */
    bool eventModeUsed;      /* FMI 3.0 CS: the importer handles events in Event Mode */
    bool earlyReturnAllowed; /* FMI 3.0 CS: fmi3DoStep may return before the end of the step */
    double startTime;
    double time;
    double maxStepSize;      /* CS: steps longer than this are discarded (not terminating); 0: any */
    /* the event iteration's results: eventUpdate() sets them */
    bool newDiscreteStatesNeeded;
    bool terminateSimulation;
    bool valuesOfContinuousStatesChanged;
    bool nextEventTimeDefined;
    double nextEventTime;
    /* FMI 3.0 input Clocks: bit i set while clockVariables()[i] is active (fmi3SetClock in Event
     * Mode, until the round of fmi3UpdateDiscreteStates that sees it); bit i of intervalsGiven once
     * fmi3GetIntervalDecimal has answered fmi3IntervalChanged for it */
    unsigned activeClocks;
    unsigned intervalsGiven;
    ModelData *data;
};

/* When a variable may be set (FMI 2.0 section 3.2.3 and 4.2.4; FMI 3.0 section 3.2 and 4.2);
 * Calculated: never (outputs and locals). */
typedef enum { Fixed, Tunable, ContinuousInput, DiscreteInput, Calculated } Settable;

/* OK when the variable `name` of kind `kind` may be set now, else logs and returns Error. */
Status checkSettable(ModelInstance *comp, const char *name, Settable kind);

/* Copies value into a STRING_SIZE buffer; Error (logged) when it does not fit. */
Status copyString(ModelInstance *comp, char *target, const char *value);

void logError(ModelInstance *comp, const char *format, ...);
void logWarning(ModelInstance *comp, const char *format, ...);
void logInfo(ModelInstance *comp, const char *format, ...);  /* only with debug logging on */

/* A time event is due at the current time (nextEventTime reached, up to round-off). */
bool timeEventDue(const ModelInstance *comp);

/* --- FMI 3.0 models: the variable table ---------------------------------------------------- */

typedef enum {
    Float32Type, Float64Type, Int8Type, UInt8Type, Int16Type, UInt16Type, Int32Type, UInt32Type,
    Int64Type, UInt64Type, BooleanType, StringType, BinaryType
} VariableType;

/* One FMI 3.0 variable: its value(s) live at `offset` in ModelData as the C type of `type`
 * (float, double, int8_t ... uint64_t, bool, char[STRING_SIZE], BinaryValue), `size` bytes in all:
 * one element for a scalar, more for an array (a 2-D array row-major, as FMI 3.0 serializes it).
 * Enumerations are Int64Type. */
typedef struct {
    ValueReference vr;
    const char *name;
    VariableType type;
    size_t offset;
    size_t size;
    Settable settable;
} Variable;

#define VARIABLE(vr, field, type, settable) \
    { vr, #field, type, offsetof(ModelData, field), sizeof(((ModelData *)0)->field), settable }

/* --- what a model implements ------------------------------------------------------------ */

extern const char *const MODEL_GUID;            /* FMI 2.0 guid, FMI 3.0 instantiationToken */
extern const size_t MODEL_DATA_SIZE;            /* sizeof(ModelData) */
extern const size_t NUMBER_OF_STATES;
extern const size_t NUMBER_OF_EVENT_INDICATORS;

/* At instantiation and reset (comp->resourceDir is set): Error (logged) fails the instantiation. */
Status setStartValues(ModelInstance *comp);
/* At ExitInitializationMode: compute what the parameters define, set the first time event. */
Status initialize(ModelInstance *comp);

/* FMI 2.0 models */
Status getReal(ModelInstance *comp, ValueReference vr, double *value);
Status setReal(ModelInstance *comp, ValueReference vr, double value);
Status getInteger(ModelInstance *comp, ValueReference vr, int *value);
Status setInteger(ModelInstance *comp, ValueReference vr, int value);
Status getBoolean(ModelInstance *comp, ValueReference vr, bool *value);
Status setBoolean(ModelInstance *comp, ValueReference vr, bool value);
Status getString(ModelInstance *comp, ValueReference vr, const char **value);
Status setString(ModelInstance *comp, ValueReference vr, const char *value);

/* FMI 3.0 models */
extern const Variable VARIABLES[];
extern const size_t NUMBER_OF_VARIABLES;
/* Brings calculated variables up to date with the inputs, parameters, states and time; Error
 * (logged) when the values set are not valid (say, an Enumeration out of its range). */
Status calculateValues(ModelInstance *comp);

void getContinuousStates(ModelInstance *comp, double x[]);
void setContinuousStates(ModelInstance *comp, const double x[]);
void getDerivatives(ModelInstance *comp, double dx[]);
void getEventIndicators(ModelInstance *comp, double z[]);

/* FMI 3.0 models with Clocks (optional: plumbing3.c's defaults say a model has none).
 * clockVariables() lists them. Periodic input Clocks: eventUpdate() sees which are active in
 * comp->activeClocks (bit i: the i-th listed); clockTiming() gives the i-th clock's interval and
 * shift as the FMU knows them after initialization (fmi3GetIntervalDecimal, fmi3GetShiftDecimal);
 * a clock whose interval is constant in the XML answers fmi3IntervalUnchanged, the others
 * fmi3IntervalChanged at the first query in Initialization Mode and fmi3IntervalUnchanged after.
 * Output Clocks: outputClockTicks() says whether the i-th ticks in the current Event Mode
 * (fmi3GetClock, before fmi3UpdateDiscreteStates runs the partitions of the active input Clocks). */
typedef struct {
    ValueReference vr;
    const char *name;
    bool constantInterval;
    bool output;
} ClockVariable;
const ClockVariable *clockVariables(size_t *n);
Status clockTiming(ModelInstance *comp, size_t i, double *interval, double *shift);
bool outputClockTicks(ModelInstance *comp, size_t i);

/* One round of the event iteration at comp->time (the flags are reset before each round). */
void eventUpdate(ModelInstance *comp);

/* Co-Simulation: integrate from comp->time towards t_stop, set comp->time to the time reached
 * and return true when the model stopped early at a state event. */
bool advance(ModelInstance *comp, double t_stop);

/* --- what common.c offers the front ends ---------------------------------------------------- */

/* A new instance with its start values set, or NULL (out of memory, or setStartValues failed). */
ModelInstance *newInstance(const char *instanceName, InterfaceType type, bool loggingOn, LogFunction log,
                           void (*logger)(void), void *environment, const char *resourceDir);
void freeInstance(ModelInstance *comp);
/* Back to the start values, as fmi2Reset and fmi3Reset want. */
Status resetInstance(ModelInstance *comp);

/* `allowed` (a mask of STATE(s)) lists the states in which `function` may be called. */
#define STATE(s) (1 << (s))
#define ANY_STATE 0xff
bool invalidState(ModelInstance *comp, const char *function, int allowed);
/* Logs "<function> is not supported" and returns Error. */
Status unsupported(ModelInstance *comp, const char *function);
/* Whether an array of n values has the expected size (logs when not). */
bool wrongSize(ModelInstance *comp, const char *function, size_t n, size_t expected);

/* One round of the event iteration with the flags reset before it. */
void eventRound(ModelInstance *comp);
/* Rounds until no new discrete states are needed or the model terminates. */
void eventIteration(ModelInstance *comp);

/* Co-Simulation: OK when a step from t by h is valid now, Discard when longer than maxStepSize,
 * Error otherwise (both logged). */
Status checkStep(ModelInstance *comp, const char *function, double t, double h);

typedef enum {
    HandleEvents,       /* events inside the step: the event iteration, here */
    ReturnAtEvents,     /* stop at the first event, leaving it to the importer's Event Mode */
    ReturnAtLastEvent,  /* handle events inside the step, leave one at its end to the importer */
} EventHandling;
typedef enum { ReachedEnd, StoppedAtEvent, StoppedTerminated } StepOutcome;
/* Advances the model to t_end (comp->time = t_end when it gets there). */
StepOutcome stepTo(ModelInstance *comp, double t_end, EventHandling handling);

/* FMU state snapshots: a copy of the model's data and the instance's time and event flags. */
size_t snapshotSize(void);
Status getSnapshot(ModelInstance *comp, void **snapshot);
Status setSnapshot(ModelInstance *comp, const void *snapshot);

#endif
