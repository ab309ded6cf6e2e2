/* The part of the Python C API the bridge uses, bound at run time with dlsym.
 *
 * The FMU's one binary must load in any host, with or without Python, and export nothing but the
 * fmi2 functions. So it is not linked against libpython and does not include Python.h: once an
 * interpreter is in the process (the host's, or the libpython the loader opened), dfmi_bind_python
 * looks up each function below in it. Only functions of the stable ABI are used (reference counts
 * through Py_IncRef/Py_DecRef, type checks through conversions), so one binary serves every
 * CPython >= 3.10. A call through this table costs what a call through the PLT costs. */
#ifndef DELTAFMI_PYAPI_H
#define DELTAFMI_PYAPI_H

#include <stddef.h>
#include <sys/types.h>
#include <wchar.h>

typedef struct _object PyObject;
typedef ssize_t Py_ssize_t;
typedef int PyGILState_STATE;
typedef struct _ts PyThreadState;

/* X(return type, name, parameter list) for every function the bridge calls */
#define DFMI_PYTHON_FUNCTIONS(X)                                                                    \
    X(int, Py_IsInitialized, (void))                                                                \
    X(void, Py_InitializeEx, (int))                                                                 \
    X(wchar_t *, Py_DecodeLocale, (const char *, size_t *))                                         \
    X(int, PyRun_SimpleString, (const char *))                                                      \
    X(PyThreadState *, PyEval_SaveThread, (void))                                                   \
    X(void, PyEval_RestoreThread, (PyThreadState *))                                                \
    X(PyThreadState *, PyGILState_GetThisThreadState, (void))                                       \
    X(PyGILState_STATE, PyGILState_Ensure, (void))                                                  \
    X(void, PyGILState_Release, (PyGILState_STATE))                                                 \
    X(void, Py_IncRef, (PyObject *))                                                                \
    X(void, Py_DecRef, (PyObject *))                                                                \
    X(void *, PyMem_Calloc, (size_t, size_t))                                                       \
    X(void, PyMem_Free, (void *))                                                                   \
    X(void, PyErr_Fetch, (PyObject **, PyObject **, PyObject **))                                   \
    X(void, PyErr_NormalizeException, (PyObject **, PyObject **, PyObject **))                      \
    X(PyObject *, PyErr_Occurred, (void))                                                           \
    X(void, PyErr_Clear, (void))                                                                    \
    X(PyObject *, PyImport_ImportModule, (const char *))                                            \
    X(PyObject *, PyObject_GetAttrString, (PyObject *, const char *))                               \
    X(PyObject *, PyObject_GetAttr, (PyObject *, PyObject *))                                       \
    X(int, PyObject_SetAttr, (PyObject *, PyObject *, PyObject *))                                  \
    X(int, PyObject_IsTrue, (PyObject *))                                                           \
    X(PyObject *, PyObject_Str, (PyObject *))                                                       \
    X(PyObject *, PyObject_Call, (PyObject *, PyObject *, PyObject *))                              \
    X(PyObject *, PyObject_CallNoArgs, (PyObject *))                                                \
    X(PyObject *, PyObject_CallFunction, (PyObject *, const char *, ...))                           \
    X(PyObject *, PyObject_CallMethod, (PyObject *, const char *, const char *, ...))               \
    X(PyObject *, PyObject_CallFunctionObjArgs, (PyObject *, ...))                                  \
    X(PyObject *, PyObject_CallMethodObjArgs, (PyObject *, PyObject *, ...))                        \
    X(int, PyArg_ParseTuple, (PyObject *, const char *, ...))                                       \
    X(PyObject *, PyTuple_New, (Py_ssize_t))                                                        \
    X(int, PyTuple_SetItem, (PyObject *, Py_ssize_t, PyObject *))                                   \
    X(PyObject *, PyTuple_GetItem, (PyObject *, Py_ssize_t))                                        \
    X(Py_ssize_t, PyTuple_Size, (PyObject *))                                                       \
    X(PyObject *, PyList_New, (Py_ssize_t))                                                         \
    X(Py_ssize_t, PyList_Size, (PyObject *))                                                        \
    X(PyObject *, PyList_GetItem, (PyObject *, Py_ssize_t))                                         \
    X(int, PyList_SetItem, (PyObject *, Py_ssize_t, PyObject *))                                    \
    X(int, PyList_SetSlice, (PyObject *, Py_ssize_t, Py_ssize_t, PyObject *))                       \
    X(PyObject *, PyDict_GetItemString, (PyObject *, const char *))                                 \
    X(PyObject *, PyDict_New, (void))                                                               \
    X(PyObject *, PyDict_GetItem, (PyObject *, PyObject *))                                         \
    X(int, PyDict_SetItem, (PyObject *, PyObject *, PyObject *))                                    \
    X(PyObject *, PyLong_FromUnsignedLong, (unsigned long))                                         \
    X(PyObject *, PyFloat_FromDouble, (double))                                                     \
    X(double, PyFloat_AsDouble, (PyObject *))                                                       \
    X(long, PyLong_AsLong, (PyObject *))                                                            \
    X(PyObject *, PyUnicode_FromString, (const char *))                                             \
    X(PyObject *, PyUnicode_DecodeFSDefault, (const char *))                                        \
    X(PyObject *, PyUnicode_InternFromString, (const char *))                                       \
    X(PyObject *, PyUnicode_Join, (PyObject *, PyObject *))                                         \
    X(const char *, PyUnicode_AsUTF8AndSize, (PyObject *, Py_ssize_t *))                            \
    X(PyObject *, PyUnicode_AsUTF8String, (PyObject *))                                             \
    X(char *, PyBytes_AsString, (PyObject *))                                                       \
    X(int, PyBytes_AsStringAndSize, (PyObject *, char **, Py_ssize_t *))                            \
    X(PyObject *, PyBytes_FromStringAndSize, (const char *, Py_ssize_t))

#define DFMI_PYTHON_FIELD(type, name, parameters) type(*name) parameters;

typedef struct {
    DFMI_PYTHON_FUNCTIONS(DFMI_PYTHON_FIELD)
    void (*Py_SetProgramName)(const wchar_t *); /* deprecated since 3.11: used when present */
    /* exported from 3.11 (not by 3.10): used when present */
    PyObject *(*PyObject_Vectorcall)(PyObject *, PyObject *const *, size_t, PyObject *);
    PyObject *none;                             /* Py_None */
} DfmiPython;

/* The bound API (valid once dfmi_bind_python has succeeded). */
extern DfmiPython py;

/* Look every function up in `library` (a dlopen handle, or RTLD_DEFAULT for the process's global
 * scope); 0 on success, else -1 with the missing name in `error`. */
int dfmi_bind_python(void *library, char *error, size_t error_size);

#define Py_None (py.none)
#define PY_VECTORCALL_ARGUMENTS_OFFSET ((size_t)1 << (8 * sizeof(size_t) - 1))
#define Py_INCREF(o) py.Py_IncRef(o)
#define Py_XINCREF(o) py.Py_IncRef(o) /* Py_IncRef and Py_DecRef accept NULL */
#define Py_DECREF(o) py.Py_DecRef(o)
#define Py_XDECREF(o) py.Py_DecRef(o)

#endif
