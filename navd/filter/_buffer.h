/* Borrowing numpy arrays in navd's compiled parts (navd/filter/_ekf_step.c,
 * navd/filter/_window.c) through the buffer protocol, so no numpy headers are needed to
 * build them. */
#ifndef NAVD_FILTER_BUFFER_H
#define NAVD_FILTER_BUFFER_H

#include <Python.h>
#include <string.h>

/* The array as a C buffer of n float64, or 0 (no exception set) if it is not one, nor
 * writable where asked: a view, or another type, goes to the Python reference. */
static int
borrow(PyObject *obj, Py_buffer *view, Py_ssize_t n, int writable)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Clear();
        return 0;
    }
    if (view->itemsize != sizeof(double) || view->len != n * (Py_ssize_t)sizeof(double) ||
        view->format == NULL || strcmp(view->format, "d") != 0) {
        PyBuffer_Release(view);
        return 0;
    }
    return 1;
}

#endif
