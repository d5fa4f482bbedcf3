/* The default mode's prediction step, compiled: the same arithmetic as
 * navd/filter/ekf_step.py's predict_step (its reference, and the fallback where no C
 * compiler was at hand when navd was installed).  A replay takes this step twice a
 * tick for every tick of a mission, and in numpy its 8x8 products cost more in calls
 * than in arithmetic.
 *
 * Only the ordinary step is taken here: a move short enough for one midpoint step
 * along the geodesic (navd.geodesy.destination, whose limit and ellipsoid the caller
 * passes in) with finite inputs.  Anything else returns None having changed nothing,
 * and the caller takes the reference step, as does an array that is not a
 * C-contiguous float64 one.  The
 * arrays are borrowed through the buffer protocol, so no numpy headers are needed to
 * build this.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_buffer.h"

#define N 8

/* Python's float modulo: the result takes the divisor's sign */
static double
py_mod(double x, double y)
{
    double m = fmod(x, y);
    if (m != 0.0) {
        if ((y < 0.0) != (m < 0.0))
            m += y;
    }
    else {
        m = copysign(0.0, y);
    }
    return m;
}

static double
wrap_lon(double lon)
{
    if (-M_PI <= lon && lon < M_PI)
        return lon;
    return py_mod(lon + M_PI, 2.0 * M_PI) - M_PI;
}

static PyObject *
predict(PyObject *self, PyObject *args)
{
    PyObject *ox, *oP, *oF, *oQ;
    double dt, heading, speed, hd, phi, q_off;
    double speed_std, heading_std, tau, cur_walk, bias_walk, scale_walk, a, e2, midpoint_max;
    if (!PyArg_ParseTuple(args, "OOOOdddddd(dddddd)(ddd)", &ox, &oP, &oF, &oQ, &dt, &heading,
                          &speed, &hd, &phi, &q_off, &speed_std, &heading_std, &tau, &cur_walk,
                          &bias_walk, &scale_walk, &a, &e2, &midpoint_max))
        return NULL;

    Py_buffer bx, bP, bF, bQ;
    int have_x = borrow(ox, &bx, N, 1), have_P = have_x && borrow(oP, &bP, N * N, 1);
    int have_F = have_P && borrow(oF, &bF, N * N, 1), have_Q = have_F && borrow(oQ, &bQ, N * N, 1);
    if (!have_Q) {
        if (have_F)
            PyBuffer_Release(&bF);
        if (have_P)
            PyBuffer_Release(&bP);
        if (have_x)
            PyBuffer_Release(&bx);
        Py_RETURN_NONE;
    }
    double *x = bx.buf, *P = bP.buf, *F = bF.buf, *Q = bQ.buf;
    PyObject *result = NULL;

    double lat = x[0], lon = x[1], cn = x[2], ce = x[3], b = x[4], s = x[5];
    double psi = heading + b;
    double u = s * speed;
    double cpsi = cos(psi), spsi = sin(psi);
    double dn = (u * cpsi + cn) * dt, de = (u * spsi + ce) * dt;
    double dist = hypot(dn, de);
    if (!(dist <= midpoint_max) || !isfinite(lat) || !isfinite(lon) || !isfinite(hd) ||
        !isfinite(phi)) {
        result = Py_NewRef(Py_None); /* not an ordinary step: the reference takes it */
        goto done;
    }

    if (dist != 0.0) {
        /* navd.geodesy.destination's midpoint rule, the azimuth from offset_position */
        double az = atan2(de, dn);
        double sl = sin(lat);
        double w2 = 1.0 - e2 * sl * sl;
        double n = a / sqrt(w2) + hd;
        double m = a * (1.0 - e2) / (w2 * sqrt(w2)) + hd;
        double h2 = 0.5 * dist;
        double lat_m = lat + h2 * (cos(az) / m);
        double az_m = az + h2 * (sin(az) * sl / (n * cos(lat)));
        sl = sin(lat_m);
        w2 = 1.0 - e2 * sl * sl;
        n = a / sqrt(w2) + hd;
        m = a * (1.0 - e2) / (w2 * sqrt(w2)) + hd;
        x[0] = lat + dist * (cos(az_m) / m);
        x[1] = wrap_lon(lon + dist * (sin(az_m) / (n * cos(lat_m))));
    }

    F[0 * N + 2] = dt;
    F[1 * N + 3] = dt;
    F[0 * N + 4] = -u * spsi * dt;
    F[1 * N + 4] = u * cpsi * dt;
    F[0 * N + 5] = speed * cpsi * dt;
    F[1 * N + 5] = speed * spsi * dt;
    F[6 * N + 6] = F[7 * N + 7] = phi;
    x[6] *= phi;
    x[7] *= phi;

    double var_along = (speed_std * speed_std) * tau * dt;
    double vc = u * heading_std;
    double var_cross = vc * vc * tau * dt;
    Q[0 * N + 0] = var_along * cpsi * cpsi + var_cross * spsi * spsi;
    Q[1 * N + 1] = var_along * spsi * spsi + var_cross * cpsi * cpsi;
    Q[0 * N + 1] = Q[1 * N + 0] = (var_along - var_cross) * cpsi * spsi;
    Q[2 * N + 2] = Q[3 * N + 3] = cur_walk * cur_walk * dt;
    Q[4 * N + 4] = bias_walk * bias_walk * dt;
    Q[5 * N + 5] = scale_walk * scale_walk * dt;
    Q[6 * N + 6] = Q[7 * N + 7] = q_off;

    /* P <- (F P F^T + (F P F^T)^T) / 2 + Q */
    double FP[N * N], M[N * N];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++)
                acc += F[i * N + k] * P[k * N + j];
            FP[i * N + j] = acc;
        }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double acc = 0.0;
            for (int k = 0; k < N; k++)
                acc += FP[i * N + k] * F[j * N + k];
            M[i * N + j] = acc;
        }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            P[i * N + j] = (M[i * N + j] + M[j * N + i]) * 0.5 + Q[i * N + j];

    result = Py_BuildValue("(ddddd)", dn, de, u, cpsi, spsi);

done:
    PyBuffer_Release(&bx);
    PyBuffer_Release(&bP);
    PyBuffer_Release(&bF);
    PyBuffer_Release(&bQ);
    return result;
}

static PyMethodDef methods[] = {
    {"predict", predict, METH_VARARGS,
     "predict(x, P, F, Q, dt, heading, speed, hd, phi, q_off, noise, geodesic): the "
     "ordinary step in place, returning (dn, de, u, cos psi, sin psi); None if the step "
     "is not an ordinary one (nothing changed)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "navd.filter._ekf_step", NULL, -1, methods,
};

PyMODINIT_FUNC
PyInit__ekf_step(void)
{
    return PyModule_Create(&module);
}
