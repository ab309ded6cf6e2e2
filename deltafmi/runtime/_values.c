/* Compiled access to a component's FMI value buffers: what ``self.x`` runs in a model.
 *
 * The pure-Python path (variables.py) is a property whose getter is a C-level methodcaller of a
 * buffer's __getitem__ and whose setter is a Python function: ~800 instructions per read and
 * ~1,800 per write of a scalar, more than the arithmetic of a small model's step. Here a
 * component (``ValueHolder``) carries the addresses of its real and integer buffers in C fields,
 * and a declaration (``ValueDescriptor``) reads or writes the scalar at its offset straight from
 * those: ~100 instructions; a real array is read as a numpy view made once, and written from a
 * list of floats or a float64 array. Whatever this does not handle (strings, integer arrays, a
 * value that is not an exact float, int or bool, a component whose buffers are not bound) goes to the
 * declaration's Python accessors, so both paths behave identically.
 *
 * Built against the stable ABI (abi3) by deltafmi.builder.compiler and bundled in every FMU;
 * without it deltafmi.runtime.native_values supplies pure-Python stand-ins.
 */
#define Py_LIMITED_API 0x030B0000 /* 3.11: the buffer protocol */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

/* Variable._kind (variables.py) */
enum { REAL_SCALAR = 0, REAL_ARRAY = 1, INT_SCALAR = 2, BOOL_SCALAR = 3 };

/* The float object last read or written for a real scalar, and its value */
typedef struct {
    PyObject *object;
    double value;
} KnownFloat;

typedef struct {
    PyObject_HEAD
    double *real;
    int32_t *ints;
    Py_ssize_t n_real, n_int;
    PyObject *real_array, *int_array; /* keep the buffers alive while their addresses are held */
    PyObject *views; /* descriptor -> its numpy view of real_array: slicing an ndarray costs ~1,000
                      * instructions, a model's right-hand side reads several arrays per call */
    KnownFloat *floats; /* per real scalar: a read whose value is unchanged (a parameter, an input
                         * the host did not change, an output the model wrote) returns the same
                         * object instead of a new float (~60 instructions with its release) */
} Holder;

typedef struct {
    PyObject_HEAD
    int kind;
    Py_ssize_t offset, size; /* first item, number of items */
    PyObject *span;       /* slice of the real buffer (REAL_ARRAY) */
    PyObject *fget, *fset; /* the Python accessors: everything the fast paths leave */
    PyObject *holder_class; /* the last class seen to derive from ValueHolder (one compare, not an MRO walk) */
} Descriptor;

static PyTypeObject *holder_type;

static void replace(PyObject **field, PyObject *value) {
    PyObject *old = *field;
    Py_INCREF(value);
    *field = value;
    Py_XDECREF(old);
}

/* tp_free, then the type's reference: the end of every dealloc of a heap type's instance */
static void free_instance(PyObject *self) {
    PyTypeObject *type = Py_TYPE(self);
    ((freefunc)PyType_GetSlot(type, Py_tp_free))(self);
    Py_DECREF(type);
}

/* ---- ValueHolder ------------------------------------------------------------------------- */

/* The address and length of a C-contiguous buffer of `format` items, or -1 with an error. */
static int address_of(PyObject *array, const char *format, Py_ssize_t itemsize, void **address,
                      Py_ssize_t *length) {
    Py_buffer view;
    if (PyObject_GetBuffer(array, &view, PyBUF_WRITABLE | PyBUF_FORMAT | PyBUF_C_CONTIGUOUS) < 0) return -1;
    int ok = view.itemsize == itemsize && view.format && strcmp(view.format, format) == 0;
    *address = view.buf;
    *length = view.len / itemsize;
    PyBuffer_Release(&view);
    if (!ok) {
        PyErr_Format(PyExc_TypeError, "a value buffer must hold C items of format '%s'", format);
        return -1;
    }
    return 0;
}

static void forget_floats(Holder *h) {
    if (!h->floats) return;
    for (Py_ssize_t i = 0; i < h->n_real; i++) Py_XDECREF(h->floats[i].object);
    PyMem_Free(h->floats);
    h->floats = NULL;
}

/* `object`, whose value is `value`, as what real scalar i holds now */
static void know_float(Holder *h, Py_ssize_t i, PyObject *object, double value) {
    KnownFloat *known = &h->floats[i];
    PyObject *old = known->object;
    known->object = Py_NewRef(object);
    known->value = value;
    Py_XDECREF(old);
}

/* Real scalar i as a Python float: the known object while the buffer holds its value bit for bit
 * (not ==: -0.0 and 0.0 differ, and a NaN is kept too) */
static PyObject *real_scalar(Holder *h, Py_ssize_t i) {
    double value = h->real[i];
    KnownFloat *known = &h->floats[i];
    if (known->object && memcmp(&known->value, &value, sizeof value) == 0) return Py_NewRef(known->object);
    PyObject *object = PyFloat_FromDouble(value);
    if (object) know_float(h, i, object, value);
    return object;
}

static PyObject *holder_bind(PyObject *self, PyObject *args) {
    Holder *h = (Holder *)self;
    PyObject *real, *ints;
    void *real_address, *int_address;
    Py_ssize_t n_real, n_int;
    if (!PyArg_ParseTuple(args, "OO:_bind_buffers", &real, &ints) ||
        address_of(real, "d", sizeof(double), &real_address, &n_real) < 0 ||
        address_of(ints, "i", sizeof(int32_t), &int_address, &n_int) < 0)
        return NULL;
    KnownFloat *floats = n_real ? PyMem_Calloc((size_t)n_real, sizeof *floats) : NULL;
    if (n_real && !floats) return PyErr_NoMemory();
    replace(&h->real_array, real);
    replace(&h->int_array, ints);
    Py_CLEAR(h->views); /* views of the previous buffers */
    forget_floats(h);
    h->floats = floats;
    h->real = real_address;
    h->ints = int_address;
    h->n_real = n_real;
    h->n_int = n_int;
    Py_RETURN_NONE;
}

static void holder_dealloc(PyObject *self) {
    Holder *h = (Holder *)self;
    Py_CLEAR(h->real_array);
    Py_CLEAR(h->int_array);
    Py_CLEAR(h->views);
    forget_floats(h);
    free_instance(self);
}

static PyMethodDef holder_methods[] = {
    {"_bind_buffers", holder_bind, METH_VARARGS,
     "_bind_buffers(real, ints): the float64 and int32 value buffers the declarations read and write."},
    {NULL, NULL, 0, NULL}};

static PyType_Slot holder_slots[] = {
    {Py_tp_doc, "Base of Component: holds the addresses of its value buffers for the declarations."},
    {Py_tp_dealloc, holder_dealloc},
    {Py_tp_methods, holder_methods},
    {0, NULL}};

static PyType_Spec holder_spec = {"deltafmi.runtime._values.ValueHolder", sizeof(Holder), 0,
                                  Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE, holder_slots};

/* ---- ValueDescriptor --------------------------------------------------------------------- */

static PyObject *descriptor_install(PyObject *self, PyObject *args) {
    Descriptor *d = (Descriptor *)self;
    int kind;
    Py_ssize_t offset;
    PyObject *span, *fget, *fset;
    Py_ssize_t start, stop, step;
    if (!PyArg_ParseTuple(args, "inOOO:_install", &kind, &offset, &span, &fget, &fset)) return NULL;
    d->size = 1;
    if (PySlice_Check(span)) {
        if (PySlice_Unpack(span, &start, &stop, &step) < 0) return NULL;
        d->size = step == 1 && stop > start ? stop - start : 0; /* 0: arrays take the Python path */
    }
    replace(&d->span, span);
    replace(&d->fget, fget);
    replace(&d->fset, fset);
    d->kind = kind;
    d->offset = offset;
    Py_RETURN_NONE;
}

/* The holder whose bound buffers cover this declaration, or NULL: take the Python path. */
static inline Holder *bound_holder(Descriptor *d, PyObject *obj) {
    PyObject *type = (PyObject *)Py_TYPE(obj);
    if (type != d->holder_class) {
        if (!PyType_IsSubtype((PyTypeObject *)type, holder_type)) return NULL;
        replace(&d->holder_class, type);
    }
    Holder *h = (Holder *)obj;
    int integer = d->kind == INT_SCALAR || d->kind == BOOL_SCALAR;
    Py_ssize_t n = integer ? h->n_int : h->n_real;
    return (integer ? (void *)h->ints : (void *)h->real) && d->offset >= 0 && d->offset + d->size <= n ? h : NULL;
}

/* The view of a real array declaration: made at its first read, the same object after that. */
static PyObject *array_view(Holder *h, Descriptor *d) {
    if (!h->views && !(h->views = PyDict_New())) return NULL;
    PyObject *view = PyDict_GetItemWithError(h->views, (PyObject *)d); /* borrowed */
    if (view) return Py_NewRef(view);
    if (PyErr_Occurred()) return NULL;
    view = PyObject_GetItem(h->real_array, d->span);
    if (view && PyDict_SetItem(h->views, (PyObject *)d, view) < 0) Py_CLEAR(view);
    return view;
}

static PyObject *descriptor_get(PyObject *self, PyObject *obj, PyObject *type) {
    Descriptor *d = (Descriptor *)self;
    (void)type;
    if (obj == NULL || obj == Py_None) return Py_NewRef(self);
    Holder *h = bound_holder(d, obj);
    if (h) {
        switch (d->kind) {
        case REAL_SCALAR: return real_scalar(h, d->offset);
        case REAL_ARRAY: return array_view(h, d);
        case INT_SCALAR: return PyLong_FromLong(h->ints[d->offset]);
        case BOOL_SCALAR: return PyBool_FromLong(h->ints[d->offset] != 0);
        }
    }
    if (!d->fget || d->fget == Py_None) {
        PyErr_SetString(PyExc_AttributeError, "unreadable attribute");
        return NULL;
    }
    return PyObject_CallFunctionObjArgs(d->fget, obj, NULL);
}

/* Items of `value` into the n doubles at out when it is a list or tuple of exact floats, or a
 * 1-D float64 buffer (a numpy array, strided or not) of length n: 0. Anything else: -1, nothing
 * written or raised (the Python path converts it with numpy, or says what is wrong). Staged
 * through a copy, as numpy does, so that a view of the same buffer (self.x = self.x[::-1]) reads
 * only values from before the write. */
static int write_array(double *out, Py_ssize_t n, PyObject *value) {
    double stack[32], *staged = n <= 32 ? stack : PyMem_Malloc((size_t)n * sizeof(double));
    int ok = 0;
    if (!staged) {
        PyErr_Clear();
        return -1;
    }
    if (PyList_CheckExact(value) || PyTuple_CheckExact(value)) {
        int list = PyList_CheckExact(value);
        ok = (list ? PyList_Size(value) : PyTuple_Size(value)) == n;
        for (Py_ssize_t i = 0; ok && i < n; i++) {
            PyObject *item = list ? PyList_GetItem(value, i) : PyTuple_GetItem(value, i);
            ok = PyFloat_CheckExact(item);
            if (ok) staged[i] = PyFloat_AsDouble(item);
        }
    } else if (PyObject_CheckBuffer(value)) {
        Py_buffer view;
        if (PyObject_GetBuffer(value, &view, PyBUF_STRIDES | PyBUF_FORMAT) == 0) {
            ok = view.ndim == 1 && view.shape[0] == n && view.itemsize == sizeof(double) && view.format &&
                 strcmp(view.format, "d") == 0;
            for (Py_ssize_t i = 0; ok && i < n; i++)
                memcpy(&staged[i], (char *)view.buf + i * view.strides[0], sizeof(double));
            PyBuffer_Release(&view);
        } else {
            PyErr_Clear();
        }
    }
    if (ok) memcpy(out, staged, (size_t)n * sizeof(double));
    if (staged != stack) PyMem_Free(staged);
    return ok ? 0 : -1;
}

static int descriptor_set(PyObject *self, PyObject *obj, PyObject *value) {
    Descriptor *d = (Descriptor *)self;
    if (value == NULL) {
        PyErr_SetString(PyExc_AttributeError, "a variable cannot be deleted");
        return -1;
    }
    if (!d->fset || d->fset == Py_None) { /* states: read-only */
        PyErr_SetString(PyExc_AttributeError, "read-only attribute");
        return -1;
    }
    Holder *h = bound_holder(d, obj);
    if (h) {
        if (d->kind == REAL_SCALAR && PyFloat_CheckExact(value)) {
            double number = PyFloat_AsDouble(value);
            h->real[d->offset] = number;
            know_float(h, d->offset, value, number);
            return 0;
        }
        if (d->kind == REAL_ARRAY && d->size > 0 && write_array(h->real + d->offset, d->size, value) == 0)
            return 0;
        if (d->kind == BOOL_SCALAR && PyBool_Check(value)) {
            h->ints[d->offset] = value == Py_True;
            return 0;
        }
        if (d->kind == INT_SCALAR && PyLong_CheckExact(value)) {
            int overflow;
            long number = PyLong_AsLongAndOverflow(value, &overflow);
            if (!overflow && number >= INT32_MIN && number <= INT32_MAX) {
                h->ints[d->offset] = (int32_t)number;
                return 0;
            }
            PyErr_Clear(); /* out of range: the Python path raises numpy's error */
        }
    }
    PyObject *result = PyObject_CallFunctionObjArgs(d->fset, obj, value, NULL);
    Py_XDECREF(result);
    return result ? 0 : -1;
}

static int descriptor_traverse(PyObject *self, visitproc visit, void *arg) {
    Descriptor *d = (Descriptor *)self;
    Py_VISIT(Py_TYPE(self));
    Py_VISIT(d->span);
    Py_VISIT(d->fget);
    Py_VISIT(d->fset);
    Py_VISIT(d->holder_class);
    return 0;
}

static int descriptor_clear(PyObject *self) {
    Descriptor *d = (Descriptor *)self;
    Py_CLEAR(d->span);
    Py_CLEAR(d->fget);
    Py_CLEAR(d->fset);
    Py_CLEAR(d->holder_class);
    return 0;
}

static void descriptor_dealloc(PyObject *self) {
    PyObject_GC_UnTrack(self);
    descriptor_clear(self);
    free_instance(self);
}

static PyMethodDef descriptor_methods[] = {
    {"_install", descriptor_install, METH_VARARGS,
     "_install(kind, offset, span, fget, fset): where the value lives and the Python accessors."},
    {NULL, NULL, 0, NULL}};

static PyType_Slot descriptor_slots[] = {
    {Py_tp_doc, "Base of Variable: a data descriptor on a ValueHolder's buffers."},
    {Py_tp_descr_get, descriptor_get},
    {Py_tp_descr_set, descriptor_set},
    {Py_tp_traverse, descriptor_traverse},
    {Py_tp_clear, descriptor_clear},
    {Py_tp_dealloc, descriptor_dealloc},
    {Py_tp_methods, descriptor_methods},
    {0, NULL}};

static PyType_Spec descriptor_spec = {"deltafmi.runtime._values.ValueDescriptor", sizeof(Descriptor), 0,
                                      Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE | Py_TPFLAGS_HAVE_GC,
                                      descriptor_slots};

/* ---- module ------------------------------------------------------------------------------ */

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_values",
                                    "Compiled access to component value buffers.", -1, NULL};

PyMODINIT_FUNC PyInit__values(void) {
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    holder_type = (PyTypeObject *)PyType_FromSpec(&holder_spec);
    PyObject *descriptor_type = PyType_FromSpec(&descriptor_spec);
    if (!holder_type || !descriptor_type ||
        PyModule_AddObjectRef(m, "ValueHolder", (PyObject *)holder_type) < 0 ||
        PyModule_AddObjectRef(m, "ValueDescriptor", descriptor_type) < 0) {
        Py_XDECREF(descriptor_type);
        Py_DECREF(m);
        return NULL;
    }
    Py_DECREF(descriptor_type); /* the module holds it; holder_type keeps its own reference */
    return m;
}
