/* The relinearised window's solve, compiled: the same arithmetic as
 * navd/filter/relinearise.py's smooth with its window_range model (the reference, and
 * the fallback where no C compiler was at hand when navd was installed).  The filter
 * solves its window after every accepted range, and in numpy the passes' 8x8 products
 * cost more in calls than in arithmetic.
 *
 * The window comes packed in float64 arrays (relinearise.solve packs them) and is
 * borrowed through the buffer protocol (_buffer.h).  An array of another shape or type
 * returns None, as a window that breaks down does; windows longer than MAX_STEPS the
 * caller solves with the reference.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_buffer.h"

#define N 8
#define NN (N * N)
#define GEO 9 /* r_ping, n_ping, e_ping, r_reply, n_reply, e_reply, lag_ping, lag_reply, tracked */
#define MAX_STEPS 64

/* c = a b (8x8) */
static void
mul(const double *a, const double *b, double *c)
{
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double s = 0.0;
            for (int k = 0; k < N; k++)
                s += a[i * N + k] * b[k * N + j];
            c[i * N + j] = s;
        }
}

/* c = a b^T (8x8) */
static void
mul_t(const double *a, const double *b, double *c)
{
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double s = 0.0;
            for (int k = 0; k < N; k++)
                s += a[i * N + k] * b[j * N + k];
            c[i * N + j] = s;
        }
}

static void
symmetrise(double *p)
{
    for (int i = 0; i < N; i++)
        for (int j = i + 1; j < N; j++) {
            double m = 0.5 * (p[i * N + j] + p[j * N + i]);
            p[i * N + j] = p[j * N + i] = m;
        }
}

/* relinearise.window_range: the round trip's range and Jacobian at d */
static double
window_range(const double *d, const double *g, double *H)
{
    double dn = d[0], de = d[1];
    int tracked = g[8] != 0.0;
    if (tracked) {
        dn -= d[6];
        de -= d[7];
    }
    double r = 0.0;
    memset(H, 0, N * sizeof(double));
    for (int leg = 0; leg < 2; leg++) {
        double length = g[3 * leg], un = g[3 * leg + 1], ue = g[3 * leg + 2];
        double lag = g[6 + leg];
        double vn = length * un + dn - d[2] * lag;
        double ve = length * ue + de - d[3] * lag;
        double vz2 = length * length * (1.0 - un * un - ue * ue);
        if (!(vz2 > 0.0))
            vz2 = 0.0;
        double l = sqrt(vn * vn + ve * ve + vz2);
        r += 0.5 * l;
        if (l > 0.0) {
            H[0] += 0.5 * vn / l;
            H[1] += 0.5 * ve / l;
            H[2] -= 0.5 * lag * vn / l;
            H[3] -= 0.5 * lag * ve / l;
        }
    }
    if (tracked) {
        H[6] = -H[0];
        H[7] = -H[1];
    }
    return r;
}

/* X = A^-1 B (8x8, B's columns), Gaussian elimination with partial pivoting; 0 if A is
 * singular */
static int
solve8(const double *A_in, const double *B_in, double *X)
{
    double A[NN];
    memcpy(A, A_in, sizeof(A));
    memcpy(X, B_in, NN * sizeof(double));
    for (int c = 0; c < N; c++) {
        int p = c;
        double best = fabs(A[c * N + c]);
        for (int r = c + 1; r < N; r++)
            if (fabs(A[r * N + c]) > best) {
                best = fabs(A[r * N + c]);
                p = r;
            }
        if (best == 0.0 || !isfinite(best))
            return 0;
        if (p != c)
            for (int j = 0; j < N; j++) {
                double t = A[c * N + j];
                A[c * N + j] = A[p * N + j];
                A[p * N + j] = t;
                t = X[c * N + j];
                X[c * N + j] = X[p * N + j];
                X[p * N + j] = t;
            }
        for (int r = c + 1; r < N; r++) {
            double f = A[r * N + c] / A[c * N + c];
            if (f == 0.0)
                continue;
            for (int j = c; j < N; j++)
                A[r * N + j] -= f * A[c * N + j];
            for (int j = 0; j < N; j++)
                X[r * N + j] -= f * X[c * N + j];
        }
    }
    for (int c = N - 1; c >= 0; c--)
        for (int j = 0; j < N; j++) {
            double s = X[c * N + j];
            for (int k = c + 1; k < N; k++)
                s -= A[c * N + k] * X[k * N + j];
            X[c * N + j] = s / A[c * N + c];
        }
    return 1;
}

struct window {
    Py_ssize_t n;
    const double *P0, *k, *phi, *qd, *geo, *z, *r_var;
};

/* One forward pass at the linearisation points lin: the filtered states about each
 * prior, before and after each range.  0 if an innovation variance is not positive. */
static int
forward(const struct window *w, const double *lin, double *d_prior, double *P_prior,
        double *d_post, double *P_post)
{
    double d[N], P[NN], T[NN], H[N], PH[N], K[N], IKH[NN];
    memset(d, 0, sizeof(d));
    memcpy(P, w->P0, sizeof(P));
    for (Py_ssize_t j = 0; j < w->n; j++) {
        if (j > 0) {
            const double *phi = w->phi + j * NN, *kp = w->k + (j - 1) * N;
            double e[N];
            for (int i = 0; i < N; i++)
                e[i] = d[i] - kp[i];
            for (int i = 0; i < N; i++) {
                double s = 0.0;
                for (int c = 0; c < N; c++)
                    s += phi[i * N + c] * e[c];
                d[i] = s;
            }
            mul(phi, P, T);
            mul_t(T, phi, P);
            for (int i = 0; i < NN; i++)
                P[i] += w->qd[j * NN + i];
        }
        memcpy(d_prior + j * N, d, sizeof(d));
        memcpy(P_prior + j * NN, P, sizeof(P));
        const double *lj = lin + j * N;
        double r = window_range(lj, w->geo + j * GEO, H);
        double hd = 0.0;
        for (int i = 0; i < N; i++)
            hd += H[i] * (d[i] - lj[i]);
        double nu = w->z[j] - r - hd;
        double S = 0.0;
        for (int i = 0; i < N; i++) {
            double s = 0.0;
            for (int c = 0; c < N; c++)
                s += P[i * N + c] * H[c];
            PH[i] = s;
        }
        for (int i = 0; i < N; i++)
            S += H[i] * PH[i];
        S += w->r_var[j];
        if (!(S > 0.0))
            return 0;
        for (int i = 0; i < N; i++) {
            K[i] = PH[i] / S;
            d[i] += K[i] * nu;
        }
        for (int i = 0; i < N; i++)
            for (int c = 0; c < N; c++)
                IKH[i * N + c] = (i == c ? 1.0 : 0.0) - K[i] * H[c];
        mul(IKH, P, T);
        mul_t(T, IKH, P);
        for (int i = 0; i < N; i++)
            for (int c = 0; c < N; c++)
                P[i * N + c] += w->r_var[j] * K[i] * K[c];
        symmetrise(P);
        memcpy(d_post + j * N, d, sizeof(d));
        memcpy(P_post + j * NN, P, sizeof(P));
    }
    return 1;
}

/* The Rauch-Tung-Striebel pass back: the smoothed states into out.  0 if a prior is
 * singular or a state is not finite. */
static int
backward(const struct window *w, const double *d_prior, const double *P_prior,
         const double *d_post, const double *P_post, double *out)
{
    Py_ssize_t n = w->n;
    double B[NN], X[NN];
    memcpy(out + (n - 1) * N, d_post + (n - 1) * N, N * sizeof(double));
    for (Py_ssize_t j = n - 2; j >= 0; j--) {
        /* G = (P_prior[j+1]^-1 (phi P_post[j]))^T */
        mul(w->phi + (j + 1) * NN, P_post + j * NN, B);
        if (!solve8(P_prior + (j + 1) * NN, B, X))
            return 0;
        double e[N];
        for (int i = 0; i < N; i++)
            e[i] = out[(j + 1) * N + i] - d_prior[(j + 1) * N + i];
        for (int i = 0; i < N; i++) {
            double s = 0.0;
            for (int c = 0; c < N; c++)
                s += X[c * N + i] * e[c];
            out[j * N + i] = d_post[j * N + i] + s;
        }
    }
    for (Py_ssize_t i = 0; i < n * N; i++)
        if (!isfinite(out[i]))
            return 0;
    return 1;
}

static PyObject *
solve(PyObject *self, PyObject *args)
{
    Py_ssize_t n;
    PyObject *oP0, *ok, *ophi, *oqd, *ogeo, *oz, *orv, *olin, *od, *oP;
    int max_passes;
    double tol;
    if (!PyArg_ParseTuple(args, "nOOOOOOOOidOO", &n, &oP0, &ok, &ophi, &oqd, &ogeo, &oz,
                          &orv, &olin, &max_passes, &tol, &od, &oP))
        return NULL;
    if (n < 2 || n > MAX_STEPS)
        Py_RETURN_NONE;
    Py_buffer b[10];
    int got = 0;
    PyObject *result = Py_None;
    PyObject *objs[10] = {oP0, ok, ophi, oqd, ogeo, oz, orv, olin, od, oP};
    Py_ssize_t sizes[10] = {NN, n * N, n * NN, n * NN, n * GEO, n, n, n * N, N, NN};
    int writable[10] = {0, 0, 0, 0, 0, 0, 0, 1, 1, 1};
    for (got = 0; got < 10; got++)
        if (!borrow(objs[got], &b[got], sizes[got], writable[got]))
            goto done;
    struct window w = {n, b[0].buf, b[1].buf, b[2].buf, b[3].buf, b[4].buf, b[5].buf, b[6].buf};
    double *lin = b[7].buf, *out_d = b[8].buf, *out_P = b[9].buf;
    static double d_prior[MAX_STEPS * N], P_prior[MAX_STEPS * NN];
    static double d_post[MAX_STEPS * N], P_post[MAX_STEPS * NN], sm[MAX_STEPS * N];
    int have = 0, passes = 0;
    while (passes < max_passes) {
        passes++;
        if (!forward(&w, lin, d_prior, P_prior, d_post, P_post))
            goto done;
        memcpy(out_d, d_post + (n - 1) * N, N * sizeof(double));
        memcpy(out_P, P_post + (n - 1) * NN, NN * sizeof(double));
        have = 1;
        if (!backward(&w, d_prior, P_prior, d_post, P_post, sm))
            goto done;
        /* the smoothed states are finite (backward checked), and so is lin */
        double moved = 0.0;
        for (Py_ssize_t j = 0; j < n; j++) {
            double m = hypot(sm[j * N] - lin[j * N], sm[j * N + 1] - lin[j * N + 1]);
            if (m > moved)
                moved = m;
        }
        memcpy(lin, sm, n * N * sizeof(double));
        if (!(moved >= tol))
            break;
    }
    if (have) {
        int finite = 1;
        for (int i = 0; i < N; i++)
            finite &= isfinite(out_d[i]);
        for (int i = 0; i < NN; i++)
            finite &= isfinite(out_P[i]);
        if (finite)
            result = PyLong_FromLong(passes);
    }
done:
    for (int i = 0; i < got; i++)
        PyBuffer_Release(&b[i]);
    if (result == Py_None)
        Py_RETURN_NONE;
    return result;
}

static PyMethodDef methods[] = {
    {"solve", solve, METH_VARARGS,
     "solve(n, P0, k, phi, qd, geometry, z, r_var, lin, max_passes, tol, d, P): the window "
     "solved into d and P (and lin left at the last smoothed states), returning the "
     "passes it took; None if it broke down or an array is not as packed."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "navd.filter._window", NULL, -1, methods,
};

PyMODINIT_FUNC
PyInit__window(void)
{
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && PyModule_AddIntConstant(m, "MAX_STEPS", MAX_STEPS) < 0)
        Py_CLEAR(m);
    return m;
}
