/* The Python side of the package's compiled libraries: an empty extension module.
 *
 * setup.py builds the C runtime (shapedisplay._engine) and the compiler's kernels
 * (shapedisplay._kernels_c) as extension modules, each with this file and SD_MODULE set
 * to its name, so that they install like any compiled part of a Python package on every
 * platform. Python calls their C functions through ctypes (shapedisplay/runtime/native.py,
 * shapedisplay/_kernels.py); importing the module itself gives an empty module. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#define SD_CAT(a, b) a##b
#define SD_INIT(name) SD_CAT(PyInit_, name)
#define SD_STR(name) SD_STR2(name)
#define SD_STR2(name) #name

static struct PyModuleDef sd_module = {
    PyModuleDef_HEAD_INIT, SD_STR(SD_MODULE),
    "C functions of shapedisplay, called through ctypes (see shapedisplay/runtime/native.py).", 0, NULL,
};

PyMODINIT_FUNC SD_INIT(SD_MODULE)(void)
{
    return PyModule_Create(&sd_module);
}
