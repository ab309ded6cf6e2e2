/* deltafmi Python bridge: the only native code that touches Python.
 *
 * Compiled into the FMU's binary, it reaches Python only through the API bound at run time
 * (pyapi.h): in the interpreter already in the process (a Python host such as fmpy) or in the
 * libpython the loader opened (a C host). One interpreter per process, started once, never
 * finalized; the GIL is released between calls, and every foreign thread gets one Python thread
 * state that it keeps (creating one per call costs ~15 us). */
#define _GNU_SOURCE
#include "glibc_floor.h"
#include <dlfcn.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "bridge.h"
#include "pyapi.h"

static const char *const OP_NAMES[DFMI_N_OPS] = {
    "enter_initialization", "exit_initialization", "evaluate", "do_step", "terminate", "reset",
    "evaluate_derivatives", "evaluate_outputs", "activate_model_partition", "cs_prepare", "cs_event", "cs_failed"};

typedef struct {
    PyObject *instance;
    PyObject *component; /* instance.component, fetched again after fmi2Reset (which replaces it) */
    PyObject *ops[DFMI_N_OPS];
    PyObject *event_update, *completed_step, *get_string, *set_string, *get_state, *set_state;
    PyObject *serialize, *deserialize;
    PyObject *directional; /* directional_derivative(time, unknowns, knowns, seed) -> bytes */
    PyObject *store_derivatives, *store_indicators; /* for results that are not lists or tuples */
    PyObject *name_component, *name_derivatives, *name_indicators, *name_time; /* interned */
    int steps_itself;        /* the component's own do_step is the whole of fmi2DoStep ... */
    int evaluates_after_step; /* ... followed by FmuInstance.evaluate (derivatives, indicators, outputs) */
    int clock_driven;        /* ... except in FMI 3.0 event mode, for a clock-driven component (Clocks, no
                              * states, no event indicators: clocks.clock_driven), whose ticks the importer
                              * activates: its step only moves time */
    PyObject *do_step;       /* component.do_step, bound (again after fmi2Reset) ... */
    PyObject *step_function; /* ... or its function, called with the component first (no method object) */
    PyObject *step_size;     /* the float of the last communication step size, passed again while the
                              * size stays the same: one float less to make per step */
    double step_size_value;
    double time;             /* instance.time after the last step_itself ... */
    int time_behind;         /* ... not yet written to instance.time (see catch_up_time) */
    PyObject *pending_logs; /* list of (status, category, message) the component queued */
    PyObject *set_log_categories;
    PyObject *strings;      /* list: last UTF-8 bytes returned per string index (keeps them alive) */
    PyObject *serialized;   /* bytes of the last serialize_state */
    DfmiLogFn log;
    void *log_env;
    int fmi3;               /* the importer speaks FMI 3.0: messages name its functions */
} Bridged;

/* The function the importer called, in its FMI version's words. */
static const char *called(const Bridged *b, const char *fmi2_name, const char *fmi3_name) {
    return b->fmi3 ? fmi3_name : fmi2_name;
}

/* fmiXInstantiate... by version and fmu_type (0 ME, 1 CS, 2 ScheduledExecution). */
static const char *instantiate_name(int fmi_version, int fmu_type) {
    static const char *const FMI3[] = {"fmi3InstantiateModelExchange", "fmi3InstantiateCoSimulation",
                                       "fmi3InstantiateScheduledExecution"};
    return fmi_version == 3 && fmu_type >= 0 && fmu_type <= 2 ? FMI3[fmu_type] : "fmi2Instantiate";
}

static pthread_mutex_t g_start_lock = PTHREAD_MUTEX_INITIALIZER;
static PyObject *g_load; /* load() of the FMU boot module, per resources directory */
static __thread int g_thread_attached;
/* This thread's slot: a one-item list in the registry's log_slots dict (keyed by thread id,
 * shared by every deltafmi FMU in the process), holding the message list of the instance whose
 * Python code runs on this thread, else None. deltafmi/runtime/fmu_logging.py sends logging
 * records and warnings there. Kept for good (a new reference), like the thread state. */
static __thread PyObject *g_slot;

DfmiPython py;

int dfmi_bind_python(void *library, char *error, size_t error_size) {
    DfmiPython api;
    void *symbol;
#define DFMI_PYTHON_BIND(type, name, parameters)                                               \
    if (!(symbol = dlsym(library, #name))) {                                                     \
        snprintf(error, error_size, "the Python library in this process lacks %s", #name);      \
        return -1;                                                                              \
    }                                                                                           \
    memcpy(&api.name, &symbol, sizeof symbol);
    DFMI_PYTHON_FUNCTIONS(DFMI_PYTHON_BIND)
#undef DFMI_PYTHON_BIND
    symbol = dlsym(library, "Py_SetProgramName");
    memcpy(&api.Py_SetProgramName, &symbol, sizeof symbol);
    symbol = dlsym(library, "PyObject_Vectorcall");
    memcpy(&api.PyObject_Vectorcall, &symbol, sizeof symbol);
    if (!(api.none = dlsym(library, "_Py_NoneStruct"))) {
        snprintf(error, error_size, "the Python library in this process lacks _Py_NoneStruct");
        return -1;
    }
    py = api;
    return 0;
}

/* ---------------------------------------------------------------------------------------- */

static void attach_thread(void) {
    if (g_thread_attached) return;
    if (py.PyGILState_GetThisThreadState() == NULL) {
        /* a thread Python has never seen: create its thread state and keep it for good by never
         * releasing this first Ensure; later Ensure/Release pairs then only take the GIL */
        py.PyGILState_Ensure();
        py.PyEval_SaveThread();
    }
    g_thread_attached = 1;
}

#define ENTER attach_thread(); PyGILState_STATE gil_ = py.PyGILState_Ensure()
#define LEAVE py.PyGILState_Release(gil_)

/* This thread's slot (see g_slot), made on first use; NULL (nothing raised) before any FMU booted. */
static PyObject *thread_slot(void) {
    if (g_slot) return g_slot;
    PyObject *registry = py.PyImport_ImportModule("_deltafmi_fmu_registry");
    PyObject *name = py.PyUnicode_InternFromString("log_slots");
    PyObject *slots = registry && name ? py.PyObject_GetAttr(registry, name) : NULL;
    if (!slots && registry && name) { /* the first instance: its runtime has not made it yet */
        py.PyErr_Clear();
        slots = py.PyDict_New();
        if (slots && py.PyObject_SetAttr(registry, name, slots) < 0) {
            Py_DECREF(slots);
            slots = NULL;
        }
    }
    PyObject *key = slots ? py.PyLong_FromUnsignedLong((unsigned long)pthread_self()) : NULL;
    PyObject *slot = key ? py.PyDict_GetItem(slots, key) : NULL; /* borrowed */
    if (slot) {
        Py_INCREF(slot);
    } else if (key && (slot = py.PyList_New(1))) {
        Py_INCREF(Py_None);
        py.PyList_SetItem(slot, 0, Py_None);
        if (py.PyDict_SetItem(slots, key, slot) < 0) {
            Py_DECREF(slot);
            slot = NULL;
        }
    }
    py.PyErr_Clear();
    Py_XDECREF(key);
    Py_XDECREF(slots);
    Py_XDECREF(name);
    Py_XDECREF(registry);
    return g_slot = slot;
}

/* Messages logged on this thread go to `sink` until unlisten(the result). Nesting-safe: an FMU
 * whose model runs another FMU gets its slot back. */
static PyObject *listen(PyObject *sink) {
    PyObject *slot = thread_slot();
    if (!slot || !sink) return NULL;
    PyObject *previous = py.PyList_GetItem(slot, 0); /* borrowed */
    Py_INCREF(previous);
    Py_INCREF(sink);
    py.PyList_SetItem(slot, 0, sink); /* steals sink, releases the list's reference to previous */
    return previous;
}

static void unlisten(PyObject *previous) {
    if (previous) py.PyList_SetItem(g_slot, 0, previous); /* steals previous */
}

/* A step of a component that steps itself and has nothing to evaluate after it does not write
 * instance.time (a Python float and a setattr: ~300 instructions of its ~3,300); every other call
 * into the instance, which may read it, writes it first. */
static void catch_up_time(Bridged *b) {
    if (!b->time_behind) return;
    b->time_behind = 0;
    PyObject *t = py.PyFloat_FromDouble(b->time);
    if (!t || py.PyObject_SetAttr(b->instance, b->name_time, t) < 0) py.PyErr_Clear(); /* out of memory only */
    Py_XDECREF(t);
}

/* Around every call into an instance's Python code: the GIL, its time, and its messages. */
#define ENTER_INSTANCE(b) ENTER; catch_up_time(b); PyObject *previous_ = listen((b)->pending_logs)
#define LEAVE_INSTANCE unlisten(previous_); LEAVE

static void send_log(Bridged *b, int status, const char *category, const char *message) {
    if (b && b->log) b->log(b->log_env, status, category, message);
}

/* Format the pending Python exception with its traceback and send it to the FMI logger. */
static void report_exception(DfmiLogFn log, void *env, const char *context) {
    PyObject *type, *value, *tb;
    py.PyErr_Fetch(&type, &value, &tb);
    py.PyErr_NormalizeException(&type, &value, &tb);
    const char *text = NULL;
    PyObject *joined = NULL, *lines = NULL, *traceback = NULL, *reported = NULL;
    PyObject *kind = type ? py.PyObject_GetAttrString(type, "__name__") : NULL;
    const char *kind_name = kind ? py.PyUnicode_AsUTF8AndSize(kind, NULL) : NULL;
    int explained = kind_name && !strcmp(kind_name, "FmuStartError"); /* a message for the user, no traceback */
    if (explained) {
        joined = py.PyObject_Str(value);
        if (joined) text = py.PyUnicode_AsUTF8AndSize(joined, NULL);
    } else {
        /* the runtime's report (component/fmu_logging.exception_report: the model's file, line and
         * function first, then the traceback), else the bare traceback */
        PyObject *registry = py.PyImport_ImportModule("_deltafmi_fmu_registry");
        PyObject *report = registry ? py.PyObject_GetAttrString(registry, "exception_report_v1") : NULL;
        if (report) reported = py.PyObject_CallFunction(report, "sOOO", context, type ? type : Py_None,
                                                     value ? value : Py_None, tb ? tb : Py_None);
        if (reported) text = py.PyUnicode_AsUTF8AndSize(reported, NULL);
        if (!text) py.PyErr_Clear();
        Py_XDECREF(report);
        Py_XDECREF(registry);
    }
    if (!explained && !text && (traceback = py.PyImport_ImportModule("traceback"))) {
        lines = py.PyObject_CallMethod(traceback, "format_exception", "OOO", type ? type : Py_None,
                                    value ? value : Py_None, tb ? tb : Py_None);
        PyObject *empty = py.PyUnicode_FromString("");
        if (lines && empty) joined = py.PyUnicode_Join(empty, lines);
        Py_XDECREF(empty);
        if (joined) text = py.PyUnicode_AsUTF8AndSize(joined, NULL);
    }
    char buffer[8192];
    if (explained && text) snprintf(buffer, sizeof buffer, "%s: %s", context, text);
    else if (reported && text) snprintf(buffer, sizeof buffer, "%s", text);
    else snprintf(buffer, sizeof buffer, "%s: Python exception\n%s", context, text ? text : "(traceback unavailable)");
    py.PyErr_Clear();
    if (log) log(env, 3, "logStatusError", buffer);
    Py_XDECREF(joined);
    Py_XDECREF(reported);
    Py_XDECREF(lines);
    Py_XDECREF(traceback);
    Py_XDECREF(kind);
    Py_XDECREF(type);
    Py_XDECREF(value);
    Py_XDECREF(tb);
}

static void drain_list(Bridged *b, PyObject *pending) {
    Py_ssize_t n = py.PyList_Size(pending);
    if (n <= 0) {
        if (n < 0) py.PyErr_Clear();
        return;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *item = py.PyList_GetItem(pending, i); /* borrowed */
        int status = 0;
        const char *category = "logComponent", *message = "";
        if (py.PyTuple_Size(item) == 3) { /* anything else raised: cleared below */
            status = (int)py.PyLong_AsLong(py.PyTuple_GetItem(item, 0));
            category = py.PyUnicode_AsUTF8AndSize(py.PyTuple_GetItem(item, 1), NULL);
            message = py.PyUnicode_AsUTF8AndSize(py.PyTuple_GetItem(item, 2), NULL);
        }
        if (py.PyErr_Occurred()) {
            py.PyErr_Clear();
            continue;
        }
        send_log(b, status, category ? category : "logComponent", message ? message : "");
    }
    py.PyList_SetSlice(pending, 0, n, NULL);
}

static void drain_logs(Bridged *b) { drain_list(b, b->pending_logs); }

/* A method's result as an FMI status: None -> OK, an int -> that status, NULL -> error. */
static int finish(Bridged *b, PyObject *result, const char *context) {
    int status = 0;
    if (!result) {
        report_exception(b->log, b->log_env, context);
        status = 3;
    } else if (result != Py_None) { /* None is OK; so is anything else but an integer */
        long value = py.PyLong_AsLong(result);
        if (value == -1 && py.PyErr_Occurred()) py.PyErr_Clear();
        else status = (int)value;
    }
    Py_XDECREF(result);
    drain_logs(b);
    return status;
}

/* ---------------------------------------------------------------------------------------- */

int bridge_start(void *python, const char *python_executable, char *error, size_t error_size) {
    pthread_mutex_lock(&g_start_lock);
    int status = dfmi_bind_python(python, error, error_size);
    if (status == 0 && !py.Py_IsInitialized()) {
        if (python_executable && python_executable[0]) {
            /* the interpreter's path decides sys.prefix, hence the site-packages (numpy, scipy) */
            static wchar_t *program; /* must outlive the interpreter */
            program = py.Py_DecodeLocale(python_executable, NULL);
            if (program && py.Py_SetProgramName) py.Py_SetProgramName(program);
        }
        py.Py_InitializeEx(0);
        if (!py.Py_IsInitialized()) {
            snprintf(error, error_size, "could not start the Python interpreter '%s'", python_executable);
            status = -1;
        } else {
            py.PyRun_SimpleString("import sys\nif not getattr(sys, 'argv', None): sys.argv = ['']\n");
            py.PyEval_SaveThread(); /* release the GIL; this thread keeps its thread state */
            g_thread_attached = 1;
        }
    }
    pthread_mutex_unlock(&g_start_lock);
    return status;
}

/* load() of resources/deltafmi_boot.py. A host may unload this binary and load it again (fmpy's
 * freeInstance does), which forgets g_load: the boot file keeps its load() in a process-wide
 * registry module, so the file runs once per process, not once per load of the binary. */
static PyObject *run_boot(const char *resources_dir, const char *function, DfmiLogFn log, void *env) {
    char path[4352];
    snprintf(path, sizeof path, "%s/deltafmi_boot.py", resources_dir);
    /* a file name is bytes: one that is not UTF-8 (a folder named in Latin-1) is decoded as
     * Python decodes file names, not refused */
    PyObject *location = py.PyUnicode_DecodeFSDefault(path);
    PyObject *registry = location ? py.PyImport_ImportModule("_deltafmi_fmu_registry") : NULL;
    PyObject *boots = registry ? py.PyObject_GetAttrString(registry, "boots") : NULL;
    g_load = boots ? py.PyDict_GetItem(boots, location) : NULL; /* borrowed */
    Py_XINCREF(g_load);
    Py_XDECREF(boots);
    Py_XDECREF(registry);
    py.PyErr_Clear();
    if (g_load || !location) {
        Py_XDECREF(location);
        return g_load;
    }
    /* imported as a module, not run from its source text: the import system keeps the file's
     * bytecode in resources/__pycache__ (where that is writable), so later processes do not parse
     * and compile it again on every instantiation of every FMU */
    PyObject *util = py.PyImport_ImportModule("importlib.util");
    PyObject *spec = util ? py.PyObject_CallMethod(util, "spec_from_file_location", "sO", "_deltafmi_boot", location)
                          : NULL;
    PyObject *module = spec ? py.PyObject_CallMethod(util, "module_from_spec", "O", spec) : NULL;
    PyObject *loader = module ? py.PyObject_GetAttrString(spec, "loader") : NULL;
    PyObject *done = loader ? py.PyObject_CallMethod(loader, "exec_module", "O", module) : NULL;
    if (done) g_load = py.PyObject_GetAttrString(module, "load"); /* a new reference, kept */
    if (!g_load) {
        char context[128];
        snprintf(context, sizeof context, "%s: loading resources/deltafmi_boot.py", function);
        report_exception(log, env, context);
    }
    Py_XDECREF(done);
    Py_XDECREF(loader);
    Py_XDECREF(module);
    Py_XDECREF(spec);
    Py_XDECREF(util);
    Py_XDECREF(location);
    return g_load;
}

/* The boot code's load(), found or run once per binary. Two threads instantiating this FMU at once:
 * the second waits for the first without holding the GIL, which the first needs to run the boot. */
static PyObject *boot_loader(const char *resources_dir, const char *function, DfmiLogFn log, void *env) {
    static pthread_mutex_t boot_lock = PTHREAD_MUTEX_INITIALIZER;
    if (g_load) return g_load;
    PyThreadState *state = py.PyEval_SaveThread();
    pthread_mutex_lock(&boot_lock);
    py.PyEval_RestoreThread(state);
    if (!g_load) run_boot(resources_dir, function, log, env);
    pthread_mutex_unlock(&boot_lock);
    return g_load;
}

static void release(Bridged *b) {
    for (int i = 0; i < DFMI_N_OPS; i++) Py_XDECREF(b->ops[i]);
    Py_XDECREF(b->event_update);
    Py_XDECREF(b->completed_step);
    Py_XDECREF(b->get_string);
    Py_XDECREF(b->set_string);
    Py_XDECREF(b->get_state);
    Py_XDECREF(b->set_state);
    Py_XDECREF(b->serialize);
    Py_XDECREF(b->deserialize);
    Py_XDECREF(b->directional);
    Py_XDECREF(b->store_derivatives);
    Py_XDECREF(b->store_indicators);
    Py_XDECREF(b->name_component);
    Py_XDECREF(b->name_derivatives);
    Py_XDECREF(b->name_indicators);
    Py_XDECREF(b->name_time);
    Py_XDECREF(b->pending_logs);
    Py_XDECREF(b->set_log_categories);
    Py_XDECREF(b->strings);
    Py_XDECREF(b->serialized);
    Py_XDECREF(b->component);
    Py_XDECREF(b->do_step);
    Py_XDECREF(b->step_function);
    Py_XDECREF(b->step_size);
    Py_XDECREF(b->instance);
    py.PyMem_Free(b);
}

/* instance.component and what fmi2DoStep of a component that steps itself calls (its bound do_step,
 * FmuInstance.step_callable): at instantiation and after fmi2Reset, which replaces the component.
 * 0, or -1 raised. */
static int fetch_component(Bridged *b) {
    Py_XDECREF(b->component);
    Py_XDECREF(b->do_step);
    Py_XDECREF(b->step_function);
    b->do_step = b->step_function = NULL;
    b->component = py.PyObject_GetAttr(b->instance, b->name_component);
    if (b->component && b->steps_itself) b->do_step = py.PyObject_CallMethod(b->instance, "step_callable", NULL);
    if (b->do_step && py.PyObject_Vectorcall) { /* a method defined in Python: call its function */
        PyObject *function = py.PyObject_GetAttrString(b->do_step, "__func__");
        PyObject *self = function ? py.PyObject_GetAttrString(b->do_step, "__self__") : NULL;
        if (self == b->component) b->step_function = function;
        else Py_XDECREF(function);
        Py_XDECREF(self);
        py.PyErr_Clear();
    }
    return b->component && (b->do_step || !b->steps_itself) ? 0 : -1;
}

void *bridge_instantiate(const char *resources_dir, const char *instance_name, const char *guid,
                         int fmi_version, int fmu_type, unsigned log_mask, DfmiLogFn log, void *log_env,
                         DfmiLayout *layout) {
    ENTER;
    const char *function = instantiate_name(fmi_version, fmu_type);
    Bridged *b = py.PyMem_Calloc(1, sizeof *b);
    PyObject *load = boot_loader(resources_dir, function, log, log_env), *spec = NULL, *early = NULL;
    if (!b || !load) goto fail;
    b->log = log;
    b->log_env = log_env;
    b->fmi3 = fmi_version == 3;
    /* what the model logs while it is imported and its setup() runs */
    early = py.PyList_New(0);
    PyObject *previous = listen(early);
    PyObject *folder = py.PyUnicode_DecodeFSDefault(resources_dir);
    b->instance = folder ? py.PyObject_CallFunction(load, "Ossi", folder, instance_name, guid, fmu_type) : NULL;
    Py_XDECREF(folder);
    unlisten(previous);
    if (early) drain_list(b, early);
    Py_XDECREF(early);
    if (!b->instance) goto python_error;
    if (!(b->set_log_categories = py.PyObject_GetAttrString(b->instance, "set_log_categories"))) goto python_error;
    PyObject *told = py.PyObject_CallFunction(b->set_log_categories, "I", log_mask);
    if (!told) goto python_error;
    Py_DECREF(told);
    spec = py.PyObject_CallMethod(b->instance, "native_layout", NULL);
    unsigned long long real, ints, flags, indicators, nominals, control, sizes3 = 0;
    unsigned long long clock_index = 0, clock_interval = 0;
    unsigned long long kernel_derivatives = 0, kernel_indicators = 0, kernel_outputs = 0, kernel_step = 0;
    unsigned long long kernel_update = 0, kernel_attributes = 0;
    unsigned long long kernels_ready = 0, kernel_drift = 0, cs = 0;
    Py_ssize_t n_real, n_int, n_str, nx, x_offset, dx_offset, nz, n_clocks = 0;
    int watches_drift;
    /* the FMI 3.0 fields trail: a runtime without them still serves an FMI 2.0 binary */
    if (!spec || !py.PyArg_ParseTuple(spec, "KnKnKnnnnKnKpppK|KnKKpKKKKKKKKK", &real, &n_real, &ints, &n_int, &flags,
                                   &n_str, &nx, &x_offset, &dx_offset, &indicators, &nz, &nominals, &watches_drift,
                                   &b->steps_itself, &b->evaluates_after_step, &control, &sizes3, &n_clocks,
                                   &clock_index, &clock_interval, &b->clock_driven, &kernel_derivatives,
                                   &kernel_indicators, &kernel_outputs, &kernel_step, &kernel_update,
                                   &kernel_attributes, &kernels_ready, &kernel_drift, &cs))
        goto python_error;
    *layout = (DfmiLayout){(double *)(uintptr_t)real, (size_t)n_real, (int *)(uintptr_t)ints, (size_t)n_int,
                           (const unsigned char *)(uintptr_t)flags, (size_t)n_str, (size_t)nx,
                           (size_t)x_offset, (size_t)dx_offset, (double *)(uintptr_t)indicators, (size_t)nz,
                           (const double *)(uintptr_t)nominals, watches_drift, (const double *)(uintptr_t)control,
                           (const uint32_t *)(uintptr_t)sizes3, (size_t)n_clocks,
                           (const int64_t *)(uintptr_t)clock_index, (const double *)(uintptr_t)clock_interval,
                           (DfmiKernelFn)(uintptr_t)kernel_derivatives, (DfmiKernelFn)(uintptr_t)kernel_indicators,
                           (DfmiKernelFn)(uintptr_t)kernel_outputs,
                           (DfmiStepFn)(uintptr_t)kernel_step, (DfmiUpdateFn)(uintptr_t)kernel_update,
                           (void *)(uintptr_t)kernel_attributes,
                           (const int *)(uintptr_t)kernels_ready, (DfmiKernelFn)(uintptr_t)kernel_drift,
                           (DfmiCs *)(uintptr_t)cs};
    for (int i = 0; i < DFMI_N_OPS; i++)
        if (!(b->ops[i] = py.PyObject_GetAttrString(b->instance, OP_NAMES[i]))) goto python_error;
    if (!(b->event_update = py.PyObject_GetAttrString(b->instance, "event_update")) ||
        !(b->completed_step = py.PyObject_GetAttrString(b->instance, "completed_integrator_step")) ||
        !(b->get_string = py.PyObject_GetAttrString(b->instance, "get_string")) ||
        !(b->set_string = py.PyObject_GetAttrString(b->instance, "set_string")) ||
        !(b->get_state = py.PyObject_GetAttrString(b->instance, "get_state")) ||
        !(b->set_state = py.PyObject_GetAttrString(b->instance, "set_state")) ||
        !(b->serialize = py.PyObject_GetAttrString(b->instance, "serialize_state")) ||
        !(b->deserialize = py.PyObject_GetAttrString(b->instance, "deserialize_state")) ||
        !(b->directional = py.PyObject_GetAttrString(b->instance, "directional_derivative")) ||
        !(b->store_derivatives = py.PyObject_GetAttrString(b->instance, "_store_derivatives")) ||
        !(b->store_indicators = py.PyObject_GetAttrString(b->instance, "_store_event_indicators")) ||
        !(b->name_component = py.PyUnicode_InternFromString("component")) ||
        !(b->name_derivatives = py.PyUnicode_InternFromString("derivatives")) ||
        !(b->name_indicators = py.PyUnicode_InternFromString("event_indicators")) ||
        fetch_component(b) < 0 ||
        !(b->name_time = py.PyUnicode_InternFromString("time")) ||
        !(b->pending_logs = py.PyObject_GetAttrString(b->instance, "pending_logs")) ||
        !(b->strings = py.PyList_New(n_str)))
        goto python_error;
    for (Py_ssize_t i = 0; i < n_str; i++) {
        Py_INCREF(Py_None);
        py.PyList_SetItem(b->strings, i, Py_None);
    }
    Py_DECREF(spec);
    drain_logs(b);
    LEAVE;
    return b;
python_error:
    report_exception(log, log_env, function);
fail:
    Py_XDECREF(spec);
    if (b) release(b);
    LEAVE;
    return NULL;
}

void bridge_free_instance(void *handle) {
    Bridged *b = handle;
    ENTER;
    /* the instance releases its solver now, not at the next garbage collection */
    PyObject *previous = listen(b->pending_logs);
    PyObject *result = py.PyObject_CallMethod(b->instance, "free", NULL);
    if (!result) py.PyErr_Clear();
    Py_XDECREF(result);
    unlisten(previous);
    drain_logs(b);
    release(b);
    LEAVE;
}

/* fmi2DoStep of a component that steps itself: what FmuInstance.do_step does for it, without that
 * Python frame (the loader has checked the communication point). */
static PyObject *step_itself(Bridged *b, double t, double h) {
    if (!b->step_size || memcmp(&b->step_size_value, &h, sizeof h) != 0) {
        Py_XDECREF(b->step_size);
        b->step_size = py.PyFloat_FromDouble(h);
        b->step_size_value = h;
    }
    PyObject *args[4] = {NULL, b->component, py.PyFloat_FromDouble(t), b->step_size};
    PyObject *stepped = NULL;
    if (b->do_step && args[2] && args[3])
        stepped = b->step_function
                      ? py.PyObject_Vectorcall(b->step_function, args + 1, 3 | PY_VECTORCALL_ARGUMENTS_OFFSET, NULL)
                      : py.PyObject_CallFunctionObjArgs(b->do_step, args[2], args[3], NULL);
    Py_XDECREF(args[2]);
    if (!stepped) return NULL;
    Py_DECREF(stepped);
    b->time = t + h;
    b->time_behind = !b->evaluates_after_step;
    if (b->time_behind) return (Py_INCREF(Py_None), Py_None);
    PyObject *end = py.PyFloat_FromDouble(t + h);
    PyObject *result = end && py.PyObject_SetAttr(b->instance, b->name_time, end) == 0
                           ? py.PyObject_CallFunctionObjArgs(b->ops[DFMI_EVALUATE], end, NULL)
                           : NULL;
    Py_XDECREF(end);
    return result;
}

int bridge_call(void *handle, DfmiOp op, const double *args, int nargs) {
    Bridged *b = handle;
    ENTER;
    PyObject *previous = listen(b->pending_logs);
    int status;
    /* FMI 3.0 event mode (args[2], DfmiStepEvents, is EARLY_RETURN or AT_STEP_END): the importer
     * handles the events FmuInstance.do_step leaves pending */
    int event_mode = op == DFMI_DO_STEP && nargs >= 3;
    if (op == DFMI_DO_STEP && b->steps_itself && !(event_mode && b->clock_driven)) {
        status = finish(b, step_itself(b, args[0], args[1]), OP_NAMES[op]);
    } else if (event_mode && b->clock_driven && !b->evaluates_after_step) {
        /* ... and all a clock-driven component does happens at its ticks, in Event Mode: its step
         * only moves time (FmuInstance.do_step would find no event and nothing to evaluate) */
        b->time = args[0] + args[1];
        b->time_behind = 1;
        status = 0; /* fmi2OK = fmi3OK */
    } else {
        catch_up_time(b);
        PyObject *tuple = py.PyTuple_New(nargs);
        for (int i = 0; i < nargs; i++) py.PyTuple_SetItem(tuple, i, py.PyFloat_FromDouble(args[i]));
        status = finish(b, py.PyObject_Call(b->ops[op], tuple, NULL), OP_NAMES[op]);
        Py_DECREF(tuple);
        if (op == DFMI_RESET && fetch_component(b) < 0) status = finish(b, NULL, called(b, "fmi2Reset", "fmi3Reset"));
    }
    unlisten(previous);
    LEAVE;
    return status;
}

void bridge_time_moved(void *handle, double time) {
    Bridged *b = handle;
    b->time = time; /* no Python here: catch_up_time writes it before the next call */
    b->time_behind = 1;
}

int bridge_set_log_mask(void *handle, unsigned log_mask) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    int status = finish(b, py.PyObject_CallFunction(b->set_log_categories, "I", log_mask),
                        called(b, "fmi2SetDebugLogging", "fmi3SetDebugLogging"));
    LEAVE_INSTANCE;
    return status;
}

/* A list or tuple of n numbers into out: 0; anything else: -1, no exception pending. */
static int copy_numbers(PyObject *values, double *out, size_t n) {
    int is_list = 1;
    Py_ssize_t size = py.PyList_Size(values);
    if (size < 0) {
        py.PyErr_Clear();
        is_list = 0;
        size = py.PyTuple_Size(values);
        if (size < 0) {
            py.PyErr_Clear();
            return -1;
        }
    }
    if ((size_t)size != n) return -1;
    for (Py_ssize_t i = 0; i < size; i++) {
        PyObject *item = is_list ? py.PyList_GetItem(values, i) : py.PyTuple_GetItem(values, i);
        double value = py.PyFloat_AsDouble(item);
        if (value == -1.0 && py.PyErr_Occurred()) {
            py.PyErr_Clear();
            return -1;
        }
        out[i] = value;
    }
    return 0;
}

/* component.<method>(t) into out (n values); any other result than a list or tuple of n numbers
 * goes to store(result) in Python, which assigns it or says what is wrong. 0, or -1 raised. */
static int evaluated_into(PyObject *component, PyObject *method, PyObject *store, PyObject *t,
                          double *out, size_t n) {
    PyObject *result = py.PyObject_CallMethodObjArgs(component, method, t, NULL);
    if (!result) return -1;
    PyObject *stored = NULL;
    if (copy_numbers(result, out, n) < 0 && !(stored = py.PyObject_CallFunctionObjArgs(store, result, NULL))) {
        Py_DECREF(result);
        return -1;
    }
    Py_XDECREF(stored);
    Py_DECREF(result);
    return 0;
}

/* What FmuInstance.evaluate_derivatives does out of initialization, without its Python frame and
 * with the results copied in C: the integrator's hot path (about 1 us less per evaluation). */
int bridge_derivatives(void *handle, double time, double *dx, size_t nx, double *z, size_t nz) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *component = b->component, *t = py.PyFloat_FromDouble(time);
    int ok = component && t &&
             (!nx || evaluated_into(component, b->name_derivatives, b->store_derivatives, t, dx, nx) == 0) &&
             (!nz || evaluated_into(component, b->name_indicators, b->store_indicators, t, z, nz) == 0);
    Py_XDECREF(t);
    int status = 0;
    if (!ok) {
        report_exception(b->log, b->log_env, "derivatives / event indicators");
        status = 3;
    }
    drain_logs(b);
    LEAVE_INSTANCE;
    return status;
}

/* After a call whose result was unpacked into C values (ok): release it and pass the logs on;
 * when the call raised or its result did not unpack, report that instead. */
static int unpacked(Bridged *b, PyObject *result, int ok, const char *context) {
    if (!ok) {
        Py_XDECREF(result);
        return finish(b, NULL, context);
    }
    Py_DECREF(result);
    drain_logs(b);
    return 0;
}

int bridge_completed_step(void *handle, double time, int *enter_event_mode) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *result = py.PyObject_CallFunction(b->completed_step, "d", time);
    int truth = result ? py.PyObject_IsTrue(result) : -1;
    *enter_event_mode = truth > 0;
    int status = unpacked(b, result, truth >= 0,
                          called(b, "fmi2CompletedIntegratorStep", "fmi3CompletedIntegratorStep"));
    LEAVE_INSTANCE;
    return status;
}

int bridge_event_update(void *handle, double time, int flags[5], double *next_event_time) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *result = py.PyObject_CallFunction(b->event_update, "d", time);
    int ok = result && py.PyArg_ParseTuple(result, "pppppd", &flags[0], &flags[1], &flags[2], &flags[3],
                                        &flags[4], next_event_time);
    int status = unpacked(b, result, ok, called(b, "fmi2NewDiscreteStates", "fmi3UpdateDiscreteStates"));
    LEAVE_INSTANCE;
    return status;
}

int bridge_get_string(void *handle, size_t index, const char **value) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    int status = 0;
    PyObject *text = py.PyObject_CallFunction(b->get_string, "n", (Py_ssize_t)index);
    PyObject *bytes = text ? py.PyUnicode_AsUTF8String(text) : NULL;
    Py_XDECREF(text);
    if (bytes) {
        *value = py.PyBytes_AsString(bytes);
        py.PyList_SetItem(b->strings, (Py_ssize_t)index, bytes); /* steals; keeps the bytes alive */
    } else {
        status = finish(b, NULL, called(b, "fmi2GetString", "fmi3GetString"));
    }
    LEAVE_INSTANCE;
    return status;
}

int bridge_set_string(void *handle, size_t index, const char *value) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    int status = finish(b, py.PyObject_CallFunction(b->set_string, "ns", (Py_ssize_t)index, value),
                        called(b, "fmi2SetString", "fmi3SetString"));
    LEAVE_INSTANCE;
    return status;
}

int bridge_get_state(void *handle, void **state) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *snapshot = py.PyObject_CallNoArgs(b->get_state);
    *state = snapshot;
    int status = snapshot ? 0 : finish(b, NULL, called(b, "fmi2GetFMUstate", "fmi3GetFMUState"));
    LEAVE_INSTANCE;
    return status;
}

int bridge_set_state(void *handle, void *state) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    int status = finish(b, py.PyObject_CallFunctionObjArgs(b->set_state, (PyObject *)state, NULL),
                        called(b, "fmi2SetFMUstate", "fmi3SetFMUState"));
    LEAVE_INSTANCE;
    return status;
}

void bridge_free_state(void *state) {
    if (!state) return;
    ENTER;
    Py_DECREF((PyObject *)state);
    LEAVE;
}

int bridge_serialize_state(void *handle, void *state, const char **bytes, size_t *size) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    int status = 0;
    PyObject *data = py.PyObject_CallFunctionObjArgs(b->serialize, (PyObject *)state, NULL);
    char *buffer;
    Py_ssize_t n;
    if (data && py.PyBytes_AsStringAndSize(data, &buffer, &n) == 0) {
        Py_XDECREF(b->serialized);
        b->serialized = data; /* keeps *bytes valid until the next call */
        *bytes = buffer;
        *size = (size_t)n;
    } else {
        Py_XDECREF(data);
        status = finish(b, NULL, called(b, "fmi2SerializeFMUstate", "fmi3SerializeFMUState"));
    }
    LEAVE_INSTANCE;
    return status;
}

int bridge_deserialize_state(void *handle, const char *bytes, size_t size, void **state) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *data = py.PyBytes_FromStringAndSize(bytes, (Py_ssize_t)size);
    PyObject *snapshot = data ? py.PyObject_CallFunctionObjArgs(b->deserialize, data, NULL) : NULL;
    Py_XDECREF(data);
    *state = snapshot;
    int status = snapshot ? 0 : finish(b, NULL, called(b, "fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"));
    LEAVE_INSTANCE;
    return status;
}

/* The value references and the seed travel as bytes (uint32 and float64 arrays), the result
 * comes back as float64 bytes: no Python API beyond bytes is needed. */
int bridge_directional_derivative(void *handle, const char *function, double time, const unsigned int *unknowns,
                                  size_t n_unknown, const unsigned int *knowns, size_t n_known, const double *seed,
                                  double *out) {
    Bridged *b = handle;
    ENTER_INSTANCE(b);
    PyObject *t = py.PyFloat_FromDouble(time);
    PyObject *u = py.PyBytes_FromStringAndSize((const char *)unknowns, (Py_ssize_t)(n_unknown * sizeof *unknowns));
    PyObject *k = py.PyBytes_FromStringAndSize((const char *)knowns, (Py_ssize_t)(n_known * sizeof *knowns));
    PyObject *s = py.PyBytes_FromStringAndSize((const char *)seed, (Py_ssize_t)(n_known * sizeof *seed));
    PyObject *result = t && u && k && s ? py.PyObject_CallFunctionObjArgs(b->directional, t, u, k, s, NULL) : NULL;
    char *bytes = NULL;
    Py_ssize_t n = 0;
    int ok = result && py.PyBytes_AsStringAndSize(result, &bytes, &n) == 0 && (size_t)n == n_unknown * sizeof *out;
    if (ok && n) memcpy(out, bytes, (size_t)n);
    Py_XDECREF(t);
    Py_XDECREF(u);
    Py_XDECREF(k);
    Py_XDECREF(s);
    int status = unpacked(b, result, ok, function);
    LEAVE_INSTANCE;
    return status;
}
