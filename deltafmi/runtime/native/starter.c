/* Start the interpreter a portable FMU carries (resources/python), in a process with no Python.
 *
 * Compiled against the headers of the Python the FMU bundles (PyConfig's layout changes between
 * versions), not linked to libpython: the loader opens the bundled libpython with RTLD_GLOBAL first,
 * and this library's Python symbols bind to it. The configuration is isolated: no environment
 * variable, no user site, no site module, no signal handlers, no change to the host's C stdio or
 * locale; the module search path is exactly the bundle's. Failures come back as a message (PyStatus),
 * never as an abort of the host. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdio.h>

#define EXPORT __attribute__((visibility("default")))

static int append(PyWideStringList *list, const char *home, const char *relative, char *error, size_t size) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", home, relative);
    wchar_t *wide = Py_DecodeLocale(path, NULL);
    if (!wide) {
        snprintf(error, size, "cannot decode the path %s", path);
        return -1;
    }
    PyStatus status = PyWideStringList_Append(list, wide);
    PyMem_RawFree(wide);
    if (PyStatus_Exception(status)) {
        snprintf(error, size, "%s", status.err_msg ? status.err_msg : "out of memory");
        return -1;
    }
    return 0;
}

/* Start the interpreter whose home is `home` (resources/python) with the module search path
 * `paths` (';'-separated, relative to home), then release the GIL. 0, or -1 with `error` set. */
EXPORT int dfmi_start_bundled(const char *home, const char *paths, char *error, size_t size) {
    PyPreConfig preconfig;
    PyPreConfig_InitIsolatedConfig(&preconfig);
    preconfig.utf8_mode = 1; /* file names as UTF-8 whatever the host's locale, which stays untouched */
    PyStatus status = Py_PreInitialize(&preconfig);
    if (PyStatus_Exception(status)) goto failed;

    PyConfig config;
    PyConfig_InitIsolatedConfig(&config);
    config.site_import = 0;
    config.install_signal_handlers = 0; /* signals belong to the host */
    config.configure_c_stdio = 0;
    config.write_bytecode = 0;          /* the bundle may be read-only */
    config.pathconfig_warnings = 0;
    config.parse_argv = 0;
    status = PyConfig_SetBytesString(&config, &config.home, home);
    if (PyStatus_Exception(status)) goto failed_config;
    status = PyConfig_SetBytesString(&config, &config.program_name, "deltafmi-fmu");
    if (PyStatus_Exception(status)) goto failed_config;
    config.module_search_paths_set = 1;
    char relative[4096];
    for (const char *p = paths; *p;) {
        size_t n = strcspn(p, ";");
        snprintf(relative, sizeof relative, "%.*s", (int)n, p);
        if (n && append(&config.module_search_paths, home, relative, error, size) < 0) {
            PyConfig_Clear(&config);
            return -1;
        }
        p += n + (p[n] == ';');
    }
    status = Py_InitializeFromConfig(&config);
    PyConfig_Clear(&config);
    if (PyStatus_Exception(status)) goto failed;
    PyEval_SaveThread(); /* the GIL is taken per call; this thread keeps its thread state */
    return 0;

failed_config:
    PyConfig_Clear(&config);
failed:
    snprintf(error, size, "the bundled Python (%s) did not start: %s%s%s", home,
             status.func ? status.func : "", status.func ? ": " : "", status.err_msg ? status.err_msg : "unknown error");
    return -1;
}
