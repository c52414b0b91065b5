/* quadest.filters._stream: the streaming call of an estimator, in C.
 *
 * An estimator's streaming ``update`` from Python spent about a microsecond of its time in its
 * own Python (the interval and vector checks, the output copy) and in numba's unboxing of eight
 * arguments, against half a microsecond in the compiled step itself (docs/developing.md, speed).
 * This object does the common case in C: it holds the estimator's state, parameter,
 * coefficient, diagnostic and streaming arrays (their data pointers taken once), checks the
 * three vectors and the interval, calls the step through a numba ``cfunc`` (the same compiled
 * step as the batch loop's) and returns a new array with the published attitude.
 *
 * Anything else -- a vector that is not a contiguous native float64 array of three, an interval
 * that is not a float in (0, max gap], arguments given in another form -- goes to the Python
 * ``update`` with the same arguments (``slow``), which converts, refuses, or restarts after a
 * gap exactly as it always did. So behaviour is that of the Python path by construction; only
 * its cost differs.
 *
 * Built by setup.py as an optional extension: without a C compiler quadest streams through the
 * Python path (quadest.filters.base.STREAM_C tells which one runs).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <math.h>

#define NPY_NO_DEPRECATED_API NPY_1_22_API_VERSION
#include <numpy/arrayobject.h>

/* the numba cfunc: step(x, nx, p, np, c, nc, gyr, acc, mag, dt, diag, nd) -> 1 if it raised */
typedef int64_t (*step_fn)(double *, Py_ssize_t, double *, Py_ssize_t, double *, Py_ssize_t,
                        double *, double *, double *, double, double *, Py_ssize_t);

typedef struct {
    PyObject_HEAD
    step_fn fn;
    PyObject *arrays[5]; /* x, p, c, diag, s (s[0]: last interval, s[1]: longest interval) */
    double *data[5];
    Py_ssize_t size[5];
    Py_ssize_t q_off;    /* offset of the published attitude in x */
    PyObject *slow;      /* the Python update: callable(gyr, acc, mag=None, *, dt) */
    vectorcallfunc vectorcall;
} Stream;

static double NAN3[3];
static PyObject *str_dt, *str_mag;

/* A contiguous, aligned, native-order float64 array of three: what the step may read raw. */
static inline double *vec3(PyObject *o) {
    if (!PyArray_CheckExact(o)) return NULL;
    PyArrayObject *a = (PyArrayObject *)o;
    if (PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 3 || PyArray_STRIDE(a, 0) != 8
        || PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_ISALIGNED(a) || !PyArray_ISNOTSWAPPED(a))
        return NULL;
    return (double *)PyArray_DATA(a);
}

static PyObject *stream_call(PyObject *self_, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    Stream *self = (Stream *)self_;
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    PyObject *dt_obj = NULL, *mag_obj = Py_None;
    if (nargs == 3) mag_obj = args[2];
    else if (nargs != 2) goto slow;
    for (Py_ssize_t i = 0; i < nkw; i++) {
        PyObject *k = PyTuple_GET_ITEM(kwnames, i);
        if (k == str_dt || PyUnicode_Compare(k, str_dt) == 0) dt_obj = args[nargs + i];
        else if (nargs == 2 && (k == str_mag || PyUnicode_Compare(k, str_mag) == 0)) mag_obj = args[nargs + i];
        else goto slow;
    }
    if (dt_obj == NULL || !PyFloat_Check(dt_obj)) goto slow;
    double dt = PyFloat_AS_DOUBLE(dt_obj);
    double *s = self->data[4];
    if (!(dt > 0.0 && dt <= s[1])) goto slow; /* a gap, NaN or <= 0: the Python path decides */
    double *g = vec3(args[0]), *a = vec3(args[1]);
    double *m = mag_obj == Py_None ? NAN3 : vec3(mag_obj);
    if (g == NULL || a == NULL || m == NULL) goto slow;
    s[0] = dt;
    if (self->fn(self->data[0], self->size[0], self->data[1], self->size[1], self->data[2], self->size[2],
                 g, a, m, dt, self->data[3], self->size[3]) != 0) {
        /* numba cannot pass an exception through a C callback; the steps guard every division,
         * so this is a bug: say so, never go on silently */
        PyErr_SetString(PyExc_RuntimeError, "the estimator's compiled step raised on this sample (the state may be "
                        "part-updated); please report it with the sample: the Python path "
                        "(quadest.filters.base.Estimator.update) shows the exception");
        return NULL;
    }
    npy_intp four = 4;
    PyObject *q = PyArray_SimpleNew(1, &four, NPY_DOUBLE);
    if (q == NULL) return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)q), self->data[0] + self->q_off, 4 * sizeof(double));
    return q;
slow:
    return PyObject_Vectorcall(self->slow, args, nargsf, kwnames);
}

static int take_array(Stream *self, int i, PyObject *o, const char *what) {
    if (!PyArray_CheckExact(o)) {
        PyErr_Format(PyExc_TypeError, "Stream: %s must be a numpy array", what);
        return -1;
    }
    PyArrayObject *a = (PyArrayObject *)o;
    if (PyArray_NDIM(a) != 1 || PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a)
        || !PyArray_ISALIGNED(a) || !PyArray_ISNOTSWAPPED(a) || !PyArray_ISWRITEABLE(a)
        || PyArray_DIM(a, 0) < 1) {
        PyErr_Format(PyExc_ValueError, "Stream: %s must be a writeable contiguous float64 vector", what);
        return -1;
    }
    Py_INCREF(o);
    self->arrays[i] = o;
    self->data[i] = (double *)PyArray_DATA(a);
    self->size[i] = PyArray_DIM(a, 0);
    return 0;
}

static int stream_clear(Stream *self) {
    for (int i = 0; i < 5; i++) Py_CLEAR(self->arrays[i]);
    Py_CLEAR(self->slow);
    return 0;
}

static int stream_traverse(Stream *self, visitproc visit, void *arg) {
    for (int i = 0; i < 5; i++) Py_VISIT(self->arrays[i]);
    Py_VISIT(self->slow);
    return 0;
}

static void stream_dealloc(Stream *self) {
    PyObject_GC_UnTrack(self);
    stream_clear(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *stream_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    static char *names[] = {"address", "x", "p", "c", "diag", "s", "q_off", "slow", NULL};
    unsigned long long address;
    PyObject *x, *p, *c, *d, *s, *slow;
    Py_ssize_t q_off;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "KOOOOOnO:Stream", names, &address, &x, &p, &c, &d, &s,
                                     &q_off, &slow))
        return NULL;
    if (address == 0) {
        PyErr_SetString(PyExc_ValueError, "Stream: the step's address is 0");
        return NULL;
    }
    if (!PyCallable_Check(slow)) {
        PyErr_SetString(PyExc_TypeError, "Stream: slow must be callable");
        return NULL;
    }
    Stream *self = (Stream *)type->tp_alloc(type, 0);
    if (self == NULL) return NULL;
    self->fn = (step_fn)(uintptr_t)address;
    self->vectorcall = stream_call;
    PyObject *objs[5] = {x, p, c, d, s};
    const char *what[5] = {"x", "p", "c", "diag", "s"};
    for (int i = 0; i < 5; i++)
        if (take_array(self, i, objs[i], what[i]) < 0) goto fail;
    if (q_off < 0 || q_off + 4 > self->size[0]) {
        PyErr_SetString(PyExc_ValueError, "Stream: q_off outside the state");
        goto fail;
    }
    if (self->size[4] < 2) {
        PyErr_SetString(PyExc_ValueError, "Stream: s needs two values (last interval, longest interval)");
        goto fail;
    }
    self->q_off = q_off;
    Py_INCREF(slow);
    self->slow = slow;
    return (PyObject *)self;
fail:
    Py_DECREF(self);
    return NULL;
}

static PyObject *stream_call_tp(PyObject *self, PyObject *args, PyObject *kwds) {
    return PyVectorcall_Call(self, args, kwds);
}

static PyTypeObject StreamType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "quadest.filters._stream.Stream",
    .tp_basicsize = sizeof(Stream),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_doc = "update(gyr, acc, mag=None, *, dt) -> q_nb: an estimator's streaming call in C "
              "(quadest.filters.base.Estimator.update, whose rules it follows).",
    .tp_new = stream_new,
    .tp_dealloc = (destructor)stream_dealloc,
    .tp_traverse = (traverseproc)stream_traverse,
    .tp_clear = (inquiry)stream_clear,
    .tp_call = stream_call_tp,
    .tp_vectorcall_offset = offsetof(Stream, vectorcall),
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_stream", "An estimator's streaming call in C (quadest.filters.base).", -1, NULL,
};

PyMODINIT_FUNC PyInit__stream(void) {
    import_array();
    for (int i = 0; i < 3; i++) NAN3[i] = NAN;
    str_dt = PyUnicode_InternFromString("dt");
    str_mag = PyUnicode_InternFromString("mag");
    if (str_dt == NULL || str_mag == NULL) return NULL;
    if (PyType_Ready(&StreamType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    Py_INCREF(&StreamType);
    if (PyModule_AddObject(m, "Stream", (PyObject *)&StreamType) < 0) {
        Py_DECREF(&StreamType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
