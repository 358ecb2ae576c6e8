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
             "pair_positions(head, t, ch, subsecond, order, head_step_s, fine_window_ns, coarse_window_ns, sys1,\n"
             "               sys2) -> (n_pairs, order, pa, pb, step_s) or None\n\n"
             "Wheel onsets in read order: head, t, ch int64, subsecond bool.  order: int64 positions sorting\n"
             "them by head, then time (ties in read order), or None: found here by a counting sort of the head\n"
             "keys, and None returned where that cannot be (a key below 0 or far above the onsets' number, or a\n"
             "head's times going back: the caller sorts).  head_step_s: float64 per head key (None: judged from\n"
             "the onsets).  pa, pb: int64 positions (into order) of each pair's Sys1 and Sys2 onset, by head,\n"
             "each head's in order; step_s: float64 per position, its head's stamp step (1.0: whole seconds).\n"
             "Bytearrays; the first n_pairs of pa, pb valid.");

static PyObject *pair_positions(PyObject *self, PyObject *args)
{
    PyObject *o_head, *o_t, *o_ch, *o_sub, *o_order, *o_step;
    long long fine_window, coarse_window, sys1, sys2;
    if (!PyArg_ParseTuple(args, "OOOOOOLLLL", &o_head, &o_t, &o_ch, &o_sub, &o_order, &o_step, &fine_window,
                          &coarse_window, &sys1, &sys2))
        return NULL;
    Buf bg = {0}, bt = {0}, bc = {0}, bs = {0}, bo = {0}, bh = {0};
    PyObject *result = NULL, *out[4] = {NULL};
    int64_t *scratch = NULL;
    if (PyObject_GetBuffer(o_head, &bg.b, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    bg.held = 1;
    const Py_ssize_t n = bg.b.len / 8;
    if (bg.b.len % 8 || get(&bt, o_t, 8, n, "t") < 0 || get(&bc, o_ch, 8, n, "ch") < 0 ||
        get(&bs, o_sub, 1, n, "subsecond") < 0)
        goto done;
    if (o_order != Py_None && get(&bo, o_order, 8, n, "order") < 0) goto done;
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
    const Py_ssize_t n1 = n > 0 ? n : 1;
    for (int k = 0; k < 4; k++) {
        out[k] = PyByteArray_FromStringAndSize(NULL, n1 * 8);
        if (!out[k]) goto done;
    }
    const int64_t *head = bg.b.buf, *t_in = bt.b.buf, *ch_in = bc.b.buf;
    const char *sub_in = bs.b.buf;
    const double *head_step = bh.held ? bh.b.buf : NULL;
    int64_t *order = (int64_t *)PyByteArray_AS_STRING(out[0]), *pa = (int64_t *)PyByteArray_AS_STRING(out[1]),
            *pb = (int64_t *)PyByteArray_AS_STRING(out[2]);
    double *step = (double *)PyByteArray_AS_STRING(out[3]);
    /* The counting sort's room: a key far above the onsets' number would cost more than a sort. */
    int64_t max_head = -1, sortable = 1;
    if (!bo.held) {
        for (Py_ssize_t i = 0; i < n; i++) {
            if (head[i] < 0) sortable = 0;
            if (head[i] > max_head) max_head = head[i];
        }
        if (max_head > 4 * (int64_t)n + 65536) sortable = 0;
        if (!sortable) {
            Py_INCREF(Py_None);
            result = Py_None;
            goto done;
        }
    }
    /* Per position: its head, time, channel (three int64 runs), its claim, then its count (the sort's). */
    size_t n_counts = bo.held ? 0 : (size_t)max_head + 2;
    scratch = PyMem_RawMalloc(((size_t)n1 * 5 + n_counts) * sizeof(int64_t));
    if (!scratch) {
        PyErr_NoMemory();
        goto done;
    }
    int64_t *gh = scratch, *t = scratch + n1, *ch = scratch + 2 * n1, *claim = scratch + 3 * n1;
    char *sub = (char *)(scratch + 4 * n1);
    int64_t m = 0;
    int bad_order = 0, went_back = 0;

    Py_BEGIN_ALLOW_THREADS
    if (bo.held) {
        const int64_t *given = bo.b.buf;
        for (Py_ssize_t i = 0; i < n; i++) {
            if (given[i] < 0 || given[i] >= n) bad_order = 1;
            order[i] = given[i];
        }
    }
    else {
        /* Stable counting sort by head key: each head's onsets keep their read order. */
        int64_t *count = scratch + 5 * n1;
        memset(count, 0, n_counts * sizeof(int64_t));
        for (Py_ssize_t i = 0; i < n; i++) count[head[i] + 1]++;
        for (size_t k = 1; k < n_counts; k++) count[k] += count[k - 1];
        for (Py_ssize_t i = 0; i < n; i++) order[count[head[i]]++] = i;
    }
    if (!bad_order)
        for (Py_ssize_t i = 0; i < n; i++) {
            int64_t o = order[i];
            gh[i] = head[o];
            t[i] = t_in[o];
            ch[i] = ch_in[o];
            sub[i] = sub_in[o];
            if (i && gh[i] == gh[i - 1] && t[i] < t[i - 1]) went_back = 1;
        }
    Py_END_ALLOW_THREADS
    if (bad_order) {
        PyErr_SetString(PyExc_IndexError, "pair_positions: an order position beyond the onsets");
        goto done;
    }
    if (went_back) {
        if (bo.held) {
            PyErr_SetString(PyExc_ValueError, "pair_positions: the order does not sort each head's times");
            goto done;
        }
        Py_INCREF(Py_None);
        result = Py_None;
        goto done;
    }

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
    result = Py_BuildValue("(LOOOO)", (long long)m, out[0], out[1], out[2], out[3]);

done:
    for (int k = 0; k < 4; k++) Py_XDECREF(out[k]);
    PyMem_RawFree(scratch);
    Buf *bufs[6] = {&bg, &bt, &bc, &bs, &bo, &bh};
    for (int k = 0; k < 6; k++)
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
