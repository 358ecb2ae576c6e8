/* The compiled pairing of wheel onsets into axles: one pass over the onsets sorted by head, then time.
 *
 * It gives what console/analysis/counting/wheels.py's numpy pairing gives, rule for rule (that is the
 * reference; tests/test_pairs_compiled.py checks both give the same pairs): per head, whether its stamps are
 * all sub-second (nearest-partner pairing) and their step; sub-second heads pair each Sys1 onset with the
 * nearest Sys2 onset of its head within the window (the earlier on a tie), a Sys2 onset claimed twice going
 * to the nearer Sys1 onset; whole-second heads pair neighbours of different systems within the window,
 * greedily from the start of each run of such neighbours.  The work runs without the GIL.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    Py_buffer b;
    int held;
} Buf;

static int get(Buf *x, PyObject *o, Py_ssize_t item, Py_ssize_t n, const char *name)
{
    if (PyObject_GetBuffer(o, &x->b, PyBUF_C_CONTIGUOUS) < 0) return -1;
    x->held = 1;
    if (x->b.len != n * item) {
        PyErr_Format(PyExc_ValueError, "pair_positions: %s has the wrong size", name);
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(pair_positions_doc,
             "pair_positions(gh, t, ch, subsecond, head_step_s, fine_window_ns, coarse_window_ns, sys1, sys2)\n"
             "    -> (n_pairs, pa, pb, step_s)\n\n"
             "Onsets sorted by head, then time (ties in read order): gh, t, ch int64, subsecond bool;\n"
             "head_step_s: float64 per head key (None: judged from the onsets).  pa, pb: int64 positions of\n"
             "each pair's Sys1 and Sys2 onset, by head, each head's in order; step_s: float64 per position,\n"
             "its head's stamp step (1.0: whole seconds).  Bytearrays; the first n_pairs of pa, pb valid.");

static PyObject *pair_positions(PyObject *self, PyObject *args)
{
    PyObject *o_gh, *o_t, *o_ch, *o_sub, *o_step;
    long long fine_window, coarse_window, sys1, sys2;
    if (!PyArg_ParseTuple(args, "OOOOOLLLL", &o_gh, &o_t, &o_ch, &o_sub, &o_step, &fine_window, &coarse_window,
                          &sys1, &sys2))
        return NULL;
    Buf bg = {0}, bt = {0}, bc = {0}, bs = {0}, bh = {0};
    PyObject *result = NULL, *out[3] = {NULL};
    int64_t *claim = NULL;
    if (PyObject_GetBuffer(o_gh, &bg.b, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    bg.held = 1;
    const Py_ssize_t n = bg.b.len / 8;
    if (bg.b.len % 8 || get(&bt, o_t, 8, n, "t") < 0 || get(&bc, o_ch, 8, n, "ch") < 0 ||
        get(&bs, o_sub, 1, n, "subsecond") < 0)
        goto done;
    Py_ssize_t n_steps = 0;
    if (o_step != Py_None) {
        if (PyObject_GetBuffer(o_step, &bh.b, PyBUF_C_CONTIGUOUS) < 0) goto done;
        bh.held = 1;
        if (bh.b.len % 8) {
            PyErr_SetString(PyExc_ValueError, "pair_positions: head_step_s must be float64");
            goto done;
        }
        n_steps = bh.b.len / 8;
    }
    static const int widths[3] = {8, 8, 8};
    for (int k = 0; k < 3; k++) {
        out[k] = PyByteArray_FromStringAndSize(NULL, (n > 0 ? n : 1) * widths[k]);
        if (!out[k]) goto done;
    }
    claim = PyMem_RawMalloc((size_t)(n > 0 ? n : 1) * sizeof(int64_t));
    if (!claim) {
        PyErr_NoMemory();
        goto done;
    }
    const int64_t *gh = bg.b.buf, *t = bt.b.buf, *ch = bc.b.buf;
    const char *sub = bs.b.buf;
    const double *head_step = bh.held ? bh.b.buf : NULL;
    int64_t *pa = (int64_t *)PyByteArray_AS_STRING(out[0]), *pb = (int64_t *)PyByteArray_AS_STRING(out[1]);
    double *step = (double *)PyByteArray_AS_STRING(out[2]);
    int64_t m = 0;

    Py_BEGIN_ALLOW_THREADS
    /* Pass 1, per head: sub-second or not, the step; the sub-second heads' nearest-partner pairs (their Sys2
       onsets' claims resolved after), the whole-second heads' neighbour pairs. */
    int any_double_claim = 0;
    int64_t s = 0;
    int64_t prev_b = -1; /* the last fine pair's Sys2 position (numpy checks neighbours in the pair list) */
    for (int64_t i = 0; i < n; i++) claim[i] = -1;
    while (s < n) {
        int64_t e = s + 1;
        while (e < n && gh[e] == gh[s]) e++;
        int fine = 1, ms = 1, us = 1;
        for (int64_t i = s; i < e; i++) {
            fine &= sub[i] != 0;
            ms &= t[i] % 1000000 == 0;
            us &= t[i] % 1000 == 0;
        }
        double st = fine ? (ms ? 1e-3 : us ? 1e-6 : 1e-9) : 1.0;
        if (head_step != NULL && gh[s] < n_steps) {
            double given = head_step[gh[s] < n_steps - 1 ? gh[s] : n_steps - 1];
            fine = given < 1.0;
            st = given;
        }
        for (int64_t i = s; i < e; i++) step[i] = st;
        if (fine) {
            /* Each Sys1 onset: the Sys2 onsets of its head just before its time and at or after it. */
            int64_t right = s; /* the first Sys2 at or after the current time */
            int64_t left = -1; /* the last Sys2 before it */
            for (int64_t i = s; i < e; i++) {
                if (ch[i] != sys1) continue;
                while (right < e && (ch[right] != sys2 || t[right] < t[i])) {
                    if (ch[right] == sys2) left = right;
                    right++;
                }
                int has_right = right < e, has_left = left >= 0;
                if (!has_right && !has_left) continue;
                int64_t r = has_right ? right : left, l = has_left ? left : right;
                int64_t d_right = t[r] > t[i] ? t[r] - t[i] : t[i] - t[r];
                int64_t d_left = t[i] > t[l] ? t[i] - t[l] : t[l] - t[i];
                int64_t pick = d_left <= d_right ? l : r;
                int64_t d = d_left < d_right ? d_left : d_right;
                if (d > fine_window) continue;
                if (pick == prev_b) any_double_claim = 1;
                prev_b = pick;
                pa[m] = i;
                pb[m] = pick;
                m++;
            }
        }
        else {
            /* Neighbours of different systems within the window, every other one of each run of them. */
            int64_t run = 0;
            for (int64_t i = s; i + 1 < e; i++) {
                int link = ch[i + 1] != ch[i] && t[i + 1] - t[i] <= coarse_window;
                if (!link) {
                    run = 0;
                    continue;
                }
                if (run % 2 == 0) {
                    pa[m] = ch[i] == sys1 ? i : i + 1;
                    pb[m] = ch[i] == sys1 ? i + 1 : i;
                    m++;
                }
                run++;
            }
            prev_b = -1;
        }
        s = e;
    }
    /* Pass 2: a Sys2 onset claimed by several Sys1 onsets goes to the nearest (the earlier pair on a tie);
       as numpy does it, only when some pair claims the Sys2 onset of the pair before it. */
    if (any_double_claim) {
        int64_t kept = 0;
        for (int64_t k = 0; k < m; k++) {
            int64_t b = pb[k];
            int64_t gap = t[b] > t[pa[k]] ? t[b] - t[pa[k]] : t[pa[k]] - t[b];
            int64_t c = claim[b];
            if (c < 0) {
                claim[b] = k;
                continue;
            }
            int64_t gap_c = t[b] > t[pa[c]] ? t[b] - t[pa[c]] : t[pa[c]] - t[b];
            if (gap < gap_c) claim[b] = k;
        }
        for (int64_t k = 0; k < m; k++) {
            if (claim[pb[k]] == k || claim[pb[k]] < 0) {
                pa[kept] = pa[k];
                pb[kept] = pb[k];
                kept++;
            }
        }
        m = kept;
    }
    Py_END_ALLOW_THREADS
    result = Py_BuildValue("(LOOO)", (long long)m, out[0], out[1], out[2]);

done:
    for (int k = 0; k < 3; k++) Py_XDECREF(out[k]);
    PyMem_RawFree(claim);
    Buf *bufs[5] = {&bg, &bt, &bc, &bs, &bh};
    for (int k = 0; k < 5; k++)
        if (bufs[k]->held) PyBuffer_Release(&bufs[k]->b);
    return result;
}

static PyMethodDef methods[] = {
    {"pair_positions", pair_positions, METH_VARARGS, pair_positions_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "compiled_pairs",
                                    "Wheel onsets paired into axles in one compiled pass.", -1, methods};

PyMODINIT_FUNC PyInit_compiled_pairs(void) { return PyModule_Create(&module); }
