/* Finding and starting the Python an FMU runs its model in (called once per FMU binary, under the
 * process-wide start-up lock of process_lock.c, by the loader's fmi2Instantiate).
 *
 * Three cases, in this order:
 * 1. The process already has Python (a Python host such as fmpy, or an earlier FMU that started
 *    one): use it. Two libpythons cannot share a process, so this wins over everything else.
 * 2. The FMU is portable (python.cfg says portable=1): check glibc against the floor recorded at
 *    build time, open the shared libraries the bundle carries (by path, so that the bundled
 *    binaries find them by soname), open the bundled libpython with RTLD_GLOBAL (extension modules
 *    expect its symbols there) and start it isolated through the bundled starter (starter.c).
 * 3. Otherwise the FMU needs the Python that built it (python.cfg: library, executable, version,
 *    stdlib), or the one named by $DELTAFMI_LIBPYTHON and $DELTAFMI_PYTHON. Everything is checked
 *    before it is started, since a Python started on a missing standard library aborts the process.
 * Every failure is one message naming what is missing, the override and `deltafmi build --portable`. */
#define _GNU_SOURCE
#include "glibc_floor.h"
#include <dlfcn.h>
#include <gnu/libc-version.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bridge.h"
#include "python_start.h"

typedef struct {
    char library[4096], executable[4096], stdlib[4096], version[32];
    char starter[4096], paths[4096], preload[8192], glibc[32];
    char source[256]; /* the component's source file, for the `deltafmi build` advice */
    int portable;
} PythonConfig;

#define ADVICE "Set DELTAFMI_PYTHON to a Python %s interpreter that has numpy installed and DELTAFMI_LIBPYTHON " \
               "to its libpython%s.so, or rebuild the FMU with `deltafmi build %s --portable`, which makes " \
               "an FMU that carries its own Python."

static void read_config(const char *resources, PythonConfig *cfg) {
    char path[4352];
    snprintf(path, sizeof path, "%s/python.cfg", resources);
    FILE *f = fopen(path, "r");
    if (!f) return;
    char line[8400];
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\r\n")] = 0;
        char *value = strchr(line, '=');
        if (!value) continue;
        *value++ = 0;
#define KEY(name) if (!strcmp(line, #name)) snprintf(cfg->name, sizeof cfg->name, "%s", value)
        KEY(library); KEY(executable); KEY(stdlib); KEY(version); KEY(starter); KEY(paths); KEY(preload); KEY(glibc);
#undef KEY
        if (!strcmp(line, "portable")) cfg->portable = atoi(value);
    }
    fclose(f);
}

/* cfg->source: the "source" of resources/deltafmi.json (written by json.dumps, so `"source": "x.py"`),
 * else "SOURCE" */
static void read_source(const char *resources, PythonConfig *cfg) {
    snprintf(cfg->source, sizeof cfg->source, "SOURCE");
    char path[4352], text[4096];
    snprintf(path, sizeof path, "%s/deltafmi.json", resources);
    FILE *f = fopen(path, "r");
    if (!f) return;
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    const char *p = strstr(text, "\"source\"");
    if (!p) return;
    p += strlen("\"source\"");
    p += strspn(p, " \t\r\n");
    if (*p++ != ':') return;
    p += strspn(p, " \t\r\n");
    if (*p++ != '"') return;
    size_t length = strcspn(p, "\"\\");
    if (length && p[length] == '"' && length < sizeof cfg->source)
        snprintf(cfg->source, sizeof cfg->source, "%.*s", (int)length, p);
}

static int version_below(const char *have, const char *need) {
    int a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
    sscanf(have, "%d.%d.%d", &a[0], &a[1], &a[2]);
    sscanf(need, "%d.%d.%d", &b[0], &b[1], &b[2]);
    for (int i = 0; i < 3; i++)
        if (a[i] != b[i]) return a[i] < b[i];
    return 0;
}

/* "3.11" of a loaded libpython (Py_GetVersion is "3.11.7 (main, ...)"), or "" */
static void library_version(void *library, char *out, size_t size) {
    const char *(*get_version)(void) = NULL;
    void *symbol = dlsym(library, "Py_GetVersion");
    memcpy(&get_version, &symbol, sizeof symbol);
    out[0] = 0;
    if (!get_version) return;
    int major = 0, minor = 0;
    if (sscanf(get_version(), "%d.%d", &major, &minor) == 2) snprintf(out, size, "%d.%d", major, minor);
}

static int start_bundled(const char *resources, const PythonConfig *cfg, char *error, size_t size) {
    const char *have = gnu_get_libc_version();
    if (cfg->glibc[0] && version_below(have, cfg->glibc)) {
        snprintf(error, size, "this portable FMU needs glibc %s or newer (the builder's); this machine has glibc "
                 "%s. Rebuild it with `deltafmi build %s --portable` on a machine whose glibc is no newer "
                 "than %s.", cfg->glibc, have, cfg->source, have);
        return -1;
    }
    char path[8600];
    for (const char *p = cfg->preload; *p;) {
        size_t n = strcspn(p, ";");
        snprintf(path, sizeof path, "%s/%.*s", resources, (int)n, p);
        if (n && !dlopen(path, RTLD_NOW | RTLD_LOCAL)) {
            snprintf(error, size, "this portable FMU cannot load its bundled library %s: %s", path, dlerror());
            return -1;
        }
        p += n + (p[n] == ';');
    }
    snprintf(path, sizeof path, "%s/%s", resources, cfg->library);
    void *python = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    if (!python) {
        snprintf(error, size, "this portable FMU cannot load its bundled Python %s: %s", path, dlerror());
        return -1;
    }
    snprintf(path, sizeof path, "%s/%s", resources, cfg->starter);
    void *starter = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    int (*start)(const char *, const char *, char *, size_t) = NULL;
    void *symbol = starter ? dlsym(starter, "dfmi_start_bundled") : NULL;
    memcpy(&start, &symbol, sizeof symbol);
    if (!start) {
        snprintf(error, size, "this portable FMU cannot load its bundled starter %s: %s", path, dlerror());
        return -1;
    }
    char home[4352];
    snprintf(home, sizeof home, "%s/python", resources);
    if (start(home, cfg->paths, error, size) != 0) return -1;
    return bridge_start(python, NULL, error, size);
}

/* "3.12" of an interpreter, from its virtual environment's pyvenv.cfg or the name it resolves to
 * (python3.12); "" when neither tells */
static void executable_version(const char *executable, char *out, size_t size) {
    out[0] = 0;
    if (!executable[0]) return;
    char path[4200];
    snprintf(path, sizeof path, "%s", executable);
    char *slash = strrchr(path, '/');
    if (slash) {
        *slash = 0;
        slash = strrchr(path, '/');
    }
    if (slash) {
        snprintf(slash, sizeof path - (size_t)(slash - path), "/pyvenv.cfg");
        FILE *f = fopen(path, "r");
        char line[512];
        int major, minor;
        while (f && fgets(line, sizeof line, f))
            if ((sscanf(line, "version_info = %d.%d", &major, &minor) == 2 ||
                 sscanf(line, "version = %d.%d", &major, &minor) == 2)) {
                snprintf(out, size, "%d.%d", major, minor);
                break;
            }
        if (f) fclose(f);
        if (out[0]) return;
    }
    char *real = realpath(executable, NULL);
    const char *name = real ? strrchr(real, '/') : NULL;
    int major, minor;
    if (name && sscanf(name, "/python%d.%d", &major, &minor) == 2) snprintf(out, size, "%d.%d", major, minor);
    free(real);
}

static int file_missing(const char *path) { return path[0] && access(path, F_OK) != 0; }

static int start_recorded(const char *resources, PythonConfig *cfg, char *error, size_t size) {
    const char *library_override = getenv("DELTAFMI_LIBPYTHON"), *executable_override = getenv("DELTAFMI_PYTHON");
    int overridden = (library_override && library_override[0]) || (executable_override && executable_override[0]);
    if (library_override && library_override[0]) snprintf(cfg->library, sizeof cfg->library, "%s", library_override);
    if (executable_override && executable_override[0])
        snprintf(cfg->executable, sizeof cfg->executable, "%s", executable_override);
    const char *version = cfg->version[0] ? cfg->version : "3";
    char what[8400] = "";
    if (!cfg->library[0])
        snprintf(what, sizeof what, "there is no Python in this process and %s/python.cfg names no Python library",
                 resources);
    else if (file_missing(cfg->library))
        snprintf(what, sizeof what, "the Python library %s %s does not exist", cfg->library,
                 library_override ? "(DELTAFMI_LIBPYTHON)" : "recorded when the FMU was built");
    else if (file_missing(cfg->executable))
        snprintf(what, sizeof what, "the Python interpreter %s %s does not exist (a deleted virtual environment?)",
                 cfg->executable, executable_override ? "(DELTAFMI_PYTHON)" : "recorded when the FMU was built");
    else if (!overridden && file_missing(cfg->stdlib))
        snprintf(what, sizeof what, "the standard library %s of the Python recorded when the FMU was built does "
                 "not exist", cfg->stdlib);
    void *python = NULL;
    if (!what[0] && !(python = dlopen(cfg->library, RTLD_NOW | RTLD_GLOBAL)))
        snprintf(what, sizeof what, "the Python library %s cannot be loaded: %s", cfg->library, dlerror());
    if (!what[0]) {
        /* the library must be the version of the interpreter whose packages it will import */
        char found[32], expected[32] = "";
        library_version(python, found, sizeof found);
        executable_version(cfg->executable, expected, sizeof expected);
        if (!expected[0] && !overridden) snprintf(expected, sizeof expected, "%s", cfg->version);
        if (expected[0] && strcmp(found, expected) != 0)
            snprintf(what, sizeof what, "%s is Python %s, but the interpreter %s whose packages it would use is "
                     "Python %s", cfg->library, found[0] ? found : "of an unknown version", cfg->executable, expected);
    }
    if (what[0]) {
        char advice[1024];
        snprintf(advice, sizeof advice, ADVICE, version, version, cfg->source);
        snprintf(error, size, "fmi2Instantiate: this FMU runs its model in Python, and %s. %s", what, advice);
        return -1;
    }
    return bridge_start(python, cfg->executable, error, size);
}

int dfmi_start_python(const char *resources, char *error, size_t size) {
    PythonConfig cfg;
    memset(&cfg, 0, sizeof cfg);
    read_config(resources, &cfg);
    read_source(resources, &cfg);
    if (dlsym(RTLD_DEFAULT, "Py_IsInitialized")) { /* a Python host, or an FMU that started one before */
        /* a host that linked libpython without starting it: start it with the recorded interpreter's
         * packages only when it is that interpreter's version, else with its own */
        char found[32];
        library_version(RTLD_DEFAULT, found, sizeof found);
        const char *executable = !cfg.portable && !strcmp(found, cfg.version) ? cfg.executable : NULL;
        return bridge_start(RTLD_DEFAULT, executable, error, size);
    }
    if (cfg.portable && !getenv("DELTAFMI_LIBPYTHON")) return start_bundled(resources, &cfg, error, size);
    return start_recorded(resources, &cfg, error, size);
}
