/* The Python side of the package's compiled libraries.
 *
 * setup.py builds the C runtime (shapedisplay._engine) and the compiler's kernels
 * (shapedisplay._kernels_c) as extension modules, each with this file and SD_MODULE set
 * to its name, so that they install like any compiled part of a Python package on every
 * platform. Python calls most of their C functions through ctypes (shapedisplay/render/native.py,
 * shapedisplay/author/kernels.py). The engine's module also defines pad_run (SD_ENGINE_METHODS): a
 * model's tick over per-tick inputs, called per short run by the reports, where a ctypes call's
 * argument conversions would cost more than the ticks. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#define SD_CAT(a, b) a##b
#define SD_INIT(name) SD_CAT(PyInit_, name)
#define SD_STR(name) SD_STR2(name)
#define SD_STR2(name) #name

#ifdef SD_ENGINE_METHODS
#include "engine/sd_runtime.h"

/* shapedisplay/render/sd_play_path.c */
int64_t sd_pad_run(int model, const sd_pad_params_t *params, sd_pad_state_t *S, const double *t, int64_t n,
                   const double *V, const double *N, const double *mus, const double *muk, const double *gain,
                   int mus_one, int muk_one, int gain_one, double *f, double *phase, double *x, double *v,
                   double *ev_t, double *ev_a, int64_t ev_cap);

/* pad_run(model, params, state, t, V, N, mus, muk, gain, out, ev) -> events (or -34: no such model).
 * Buffers (C-contiguous): params an sd_pad_params_t, state an sd_pad_state_t (updated in place); t, V, N
 * n doubles; mus, muk, gain n doubles or 1 (one value for every tick); out 4 n doubles (friction, phase,
 * stretch, pad velocity per tick); ev 2 cap doubles (event times, then amplitudes). */
static PyObject *pad_run(PyObject *self, PyObject *args)
{
    int model, i, ones[3];
    Py_buffer prm, st, in[6], out, ev;
    Py_ssize_t n;
    int64_t r = 0;
    PyObject *result = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "iy*w*y*y*y*y*y*y*w*w*", &model, &prm, &st, &in[0], &in[1], &in[2], &in[3], &in[4],
                          &in[5], &out, &ev))
        return NULL;
    n = in[0].len / (Py_ssize_t)sizeof(double);
    if (prm.len != (Py_ssize_t)sizeof(sd_pad_params_t) || st.len != (Py_ssize_t)sizeof(sd_pad_state_t)
        || in[1].len != in[0].len || in[2].len != in[0].len || out.len < 4 * in[0].len
        || ev.len % (Py_ssize_t)(2 * sizeof(double)) != 0) {
        PyErr_SetString(PyExc_ValueError, "pad_run: buffer sizes do not match (params, state, t, V, N, out, ev)");
        goto done;
    }
    for (i = 0; i < 3; i++) {
        Py_ssize_t len = in[3 + i].len;
        if (len != in[0].len && !(len == (Py_ssize_t)sizeof(double) && n > 0)) {
            PyErr_SetString(PyExc_ValueError, "pad_run: mus, muk and gain hold n values or one");
            goto done;
        }
        ones[i] = len != in[0].len;
    }
    {
        double *o = (double *)out.buf, *e = (double *)ev.buf;
        int64_t cap = (int64_t)(ev.len / (Py_ssize_t)(2 * sizeof(double)));
        Py_BEGIN_ALLOW_THREADS
        r = sd_pad_run(model, (const sd_pad_params_t *)prm.buf, (sd_pad_state_t *)st.buf, (const double *)in[0].buf,
                       (int64_t)n, (const double *)in[1].buf, (const double *)in[2].buf, (const double *)in[3].buf,
                       (const double *)in[4].buf, (const double *)in[5].buf, ones[0], ones[1], ones[2], o, o + n,
                       o + 2 * n, o + 3 * n, e, e + cap, cap);
        Py_END_ALLOW_THREADS
    }
    result = PyLong_FromLongLong((long long)r);
done:
    PyBuffer_Release(&prm);
    PyBuffer_Release(&st);
    for (i = 0; i < 6; i++) PyBuffer_Release(&in[i]);
    PyBuffer_Release(&out);
    PyBuffer_Release(&ev);
    return result;
}

static PyMethodDef sd_methods[] = {
    {"pad_run", pad_run, METH_VARARGS, "A pad model's C tick over per-tick inputs (see shapedisplay.render.models.run_kernel)."},
    {NULL, NULL, 0, NULL},
};
#define SD_METHODS sd_methods
#else
#define SD_METHODS NULL
#endif

static struct PyModuleDef sd_module = {
    PyModuleDef_HEAD_INIT, SD_STR(SD_MODULE),
    "C functions of shapedisplay (see shapedisplay/render/native.py).", 0, SD_METHODS,
};

PyMODINIT_FUNC SD_INIT(SD_MODULE)(void)
{
    return PyModule_Create(&sd_module);
}
