/* The compiled reduction of a chunk's records to activity runs: one pass over the records.
 *
 * It does what console/analysis/passages/buckets.py's chunk_buckets and the head and wheel lookups of
 * DiagAccumulator.add do, rule for rule (the numpy path is the reference; tests/test_passages_compiled.py
 * checks both give the same columns): each record's head key from its register, runs of consecutive
 * records of one (head, whole second) with their counts and first and last times, overall and per system,
 * and the positions of the wheel-sensor records wanted.  The passes run without the GIL; only the
 * allocation of the outputs holds it.
 *
 * Outputs are bytearrays (wrapped by numpy in Python), so the build needs the Python headers only.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#define NS_PER_S 1000000000LL
#define N_RUN_COLUMNS 12

/* numpy's floor division: times before 1970 fall in the second below. */
static inline int64_t floor_second(int64_t t)
{
    int64_t q = t / NS_PER_S;
    return (t % NS_PER_S < 0) ? q - 1 : q;
}

typedef struct {
    Py_buffer rid, time_ns, subsecond, value, head_lut, channel_lut, wheel_lut;
} Inputs;

static int get(PyObject *o, Py_buffer *b, Py_ssize_t itemsize, const char *name)
{
    if (PyObject_GetBuffer(o, b, PyBUF_C_CONTIGUOUS) < 0) return -1;
    if (b->len % itemsize != 0) {
        PyBuffer_Release(b);
        PyErr_Format(PyExc_ValueError, "chunk_runs: %s is not of %zd-byte items", name, itemsize);
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(chunk_runs_doc,
             "chunk_runs(register_id, time_ns, subsecond, value, head_lut, channel_lut, wheel_lut, keep_releases)\n"
             "    -> (head, runs, n_runs, wheel)\n\n"
             "register_id int32, time_ns int64, subsecond bool and value int64 per record; head_lut int32,\n"
             "channel_lut int8 and wheel_lut bool per register.  head: int64 per record; runs: the 12 run\n"
             "columns of buckets.BUCKET_COLUMNS one after another, n_runs int64 each; wheel: int64 positions\n"
             "of the wheel-sensor records with value 1 (or 0 too, with keep_releases).");

static PyObject *chunk_runs(PyObject *self, PyObject *args)
{
    PyObject *o[7];
    int keep_releases;
    if (!PyArg_ParseTuple(args, "OOOOOOOp", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &keep_releases))
        return NULL;
    Inputs in;
    Py_buffer *bufs[7] = {&in.rid, &in.time_ns, &in.subsecond, &in.value, &in.head_lut, &in.channel_lut,
                          &in.wheel_lut};
    static const Py_ssize_t sizes[7] = {4, 8, 1, 8, 4, 1, 1};
    static const char *names[7] = {"register_id", "time_ns", "subsecond", "value", "head_lut", "channel_lut",
                                   "wheel_lut"};
    int got = 0;
    for (; got < 7; got++)
        if (get(o[got], bufs[got], sizes[got], names[got]) < 0) goto release;

    const int64_t n = (int64_t)(in.rid.len / 4);
    const int64_t n_registers = (int64_t)(in.head_lut.len / 4);
    if (in.time_ns.len / 8 != n || in.subsecond.len != n || in.value.len / 8 != n ||
        in.channel_lut.len != n_registers || in.wheel_lut.len != n_registers) {
        PyErr_SetString(PyExc_ValueError, "chunk_runs: the record columns or the register tables differ in length");
        goto release;
    }
    const int32_t *rid = in.rid.buf, *head_lut = in.head_lut.buf;
    const int64_t *time_ns = in.time_ns.buf, *value = in.value.buf;
    const unsigned char *subsecond = in.subsecond.buf, *wheel_lut = in.wheel_lut.buf;
    const int8_t *channel_lut = in.channel_lut.buf;

    PyObject *head_out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n * 8));
    if (!head_out) goto release;
    int64_t *head = (int64_t *)PyByteArray_AS_STRING(head_out);
    int64_t n_runs = 0, n_wheel = 0, bad_register = -1;
    Py_BEGIN_ALLOW_THREADS
    int64_t prev_head = 0, prev_second = 0;
    for (int64_t i = 0; i < n; i++) {
        int32_t r = rid[i];
        if (r < 0 || r >= n_registers) {
            bad_register = i;
            break;
        }
        int64_t h = head_lut[r], s = floor_second(time_ns[i]);
        head[i] = h;
        n_runs += i == 0 || h != prev_head || s != prev_second;
        prev_head = h;
        prev_second = s;
        n_wheel += wheel_lut[r] && (value[i] == 1 || (keep_releases && value[i] == 0));
    }
    Py_END_ALLOW_THREADS
    if (bad_register >= 0) {
        Py_DECREF(head_out);
        PyErr_Format(PyExc_IndexError, "chunk_runs: record %lld names no register of the tables",
                     (long long)bad_register);
        goto release;
    }
    PyObject *runs_out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n_runs * 8 * N_RUN_COLUMNS));
    PyObject *wheel_out = runs_out ? PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n_wheel * 8)) : NULL;
    if (!wheel_out) {
        Py_XDECREF(runs_out);
        Py_DECREF(head_out);
        goto release;
    }
    int64_t *cols = (int64_t *)PyByteArray_AS_STRING(runs_out), *wheel = (int64_t *)PyByteArray_AS_STRING(wheel_out);
    Py_BEGIN_ALLOW_THREADS
    /* Columns in the order of buckets.BUCKET_COLUMNS. */
    int64_t *c_head = cols, *c_second = cols + n_runs, *c_records = cols + 2 * n_runs,
            *c_sys1 = cols + 3 * n_runs, *c_sys2 = cols + 4 * n_runs, *c_whole = cols + 5 * n_runs,
            *c_first = cols + 6 * n_runs, *c_first1 = cols + 7 * n_runs, *c_first2 = cols + 8 * n_runs,
            *c_last = cols + 9 * n_runs, *c_last1 = cols + 10 * n_runs, *c_last2 = cols + 11 * n_runs;
    int64_t k = -1, w = 0;
    for (int64_t i = 0; i < n; i++) {
        int32_t r = rid[i];
        int64_t h = head[i], t = time_ns[i], s = floor_second(t);
        if (k < 0 || h != c_head[k] || s != c_second[k]) {
            k++;
            c_head[k] = h;
            c_second[k] = s;
            c_records[k] = c_sys1[k] = c_sys2[k] = c_whole[k] = 0;
            c_first[k] = c_first1[k] = c_first2[k] = INT64_MAX;
            c_last[k] = c_last1[k] = c_last2[k] = INT64_MIN;
        }
        c_records[k]++;
        c_whole[k] += !subsecond[i];
        if (t < c_first[k]) c_first[k] = t;
        if (t > c_last[k]) c_last[k] = t;
        int8_t ch = channel_lut[r];
        if (ch == 1) {
            c_sys1[k]++;
            if (t < c_first1[k]) c_first1[k] = t;
            if (t > c_last1[k]) c_last1[k] = t;
        }
        else if (ch == 2) {
            c_sys2[k]++;
            if (t < c_first2[k]) c_first2[k] = t;
            if (t > c_last2[k]) c_last2[k] = t;
        }
        if (wheel_lut[r] && (value[i] == 1 || (keep_releases && value[i] == 0))) wheel[w++] = i;
    }
    Py_END_ALLOW_THREADS
    for (int b = 0; b < 7; b++) PyBuffer_Release(bufs[b]);
    return Py_BuildValue("(NNLN)", head_out, runs_out, (long long)n_runs, wheel_out);

release:
    for (int b = 0; b < got; b++) PyBuffer_Release(bufs[b]);
    return NULL;
}

PyDoc_STRVAR(head_spans_doc,
             "head_spans(head, time_ns, gap_ns, slot) -> (n, heads, first, last, before, after) | None\n\n"
             "Per head key in a chunk (in order of first appearance): its first and last record time, and\n"
             "around its last pause longer than gap_ns, the times before and after it (before = after =\n"
             "INT64_MIN: no pause).  head and time_ns: int64 per record.  slot: int32 per head key, -1 on\n"
             "entry, and -1 again on return (scratch the caller keeps).  None where a head's times go back\n"
             "(the caller sorts).  Outputs are int64 bytearrays of one item per record, the first n valid.");

static PyObject *head_spans(PyObject *self, PyObject *args)
{
    PyObject *o_head, *o_time, *o_slot;
    long long gap_ns;
    if (!PyArg_ParseTuple(args, "OOLO", &o_head, &o_time, &gap_ns, &o_slot)) return NULL;
    Py_buffer bh, bt, bs;
    if (PyObject_GetBuffer(o_head, &bh, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    if (PyObject_GetBuffer(o_time, &bt, PyBUF_C_CONTIGUOUS) < 0) {
        PyBuffer_Release(&bh);
        return NULL;
    }
    if (PyObject_GetBuffer(o_slot, &bs, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) {
        PyBuffer_Release(&bh);
        PyBuffer_Release(&bt);
        return NULL;
    }
    PyObject *result = NULL, *out[5] = {NULL};
    const int64_t n = (int64_t)(bh.len / 8), n_slots = (int64_t)(bs.len / 4);
    if (bh.len % 8 || bs.len % 4 || bt.len != bh.len) {
        PyErr_SetString(PyExc_ValueError, "head_spans: head and time_ns must be int64 of one length, slot int32");
        goto done;
    }
    for (int k = 0; k < 5; k++) {
        out[k] = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n * 8));
        if (!out[k]) goto done;
    }
    const int64_t *head = bh.buf, *t = bt.buf;
    int32_t *slot = bs.buf;
    int64_t *heads = (int64_t *)PyByteArray_AS_STRING(out[0]), *first = (int64_t *)PyByteArray_AS_STRING(out[1]),
            *last = (int64_t *)PyByteArray_AS_STRING(out[2]), *before = (int64_t *)PyByteArray_AS_STRING(out[3]),
            *after = (int64_t *)PyByteArray_AS_STRING(out[4]);
    int64_t m = 0;
    int status = 0; /* 1: a head beyond the slots; 2: a head's times go back */
    Py_BEGIN_ALLOW_THREADS
    for (int64_t i = 0; i < n; i++) {
        int64_t h = head[i];
        if (h < 0 || h >= n_slots) {
            status = 1;
            break;
        }
        int32_t k = slot[h];
        if (k < 0) {
            k = slot[h] = (int32_t)m++;
            heads[k] = h;
            first[k] = last[k] = t[i];
            before[k] = after[k] = INT64_MIN;
            continue;
        }
        if (t[i] < last[k]) {
            status = 2;
            break;
        }
        if (t[i] - last[k] > gap_ns) {
            before[k] = last[k];
            after[k] = t[i];
        }
        last[k] = t[i];
    }
    for (int64_t k = 0; k < m; k++) slot[heads[k]] = -1;
    Py_END_ALLOW_THREADS
    if (status == 1) {
        PyErr_SetString(PyExc_IndexError, "head_spans: a head key beyond the slots");
        goto done;
    }
    if (status == 2) {
        Py_INCREF(Py_None);
        result = Py_None;
        goto done;
    }
    result = Py_BuildValue("(LOOOOO)", (long long)m, out[0], out[1], out[2], out[3], out[4]);

done:
    for (int k = 0; k < 5; k++) Py_XDECREF(out[k]);
    PyBuffer_Release(&bh);
    PyBuffer_Release(&bt);
    PyBuffer_Release(&bs);
    return result;
}

PyDoc_STRVAR(merge_runs_doc,
             "merge_runs(order, columns) -> (n, merged)\n\n"
             "Runs (columns: the 12 int64 columns of buckets.BUCKET_COLUMNS one after another, n_runs each)\n"
             "taken in ``order`` (int64 positions sorting them by head and second) and combined into one per\n"
             "head and second: counts added, first times the least, last times the greatest.  merged: the\n"
             "12 columns one after another, n_runs each, the first n of each valid.");

static PyObject *merge_runs(PyObject *self, PyObject *args)
{
    PyObject *o_order, *o_cols;
    if (!PyArg_ParseTuple(args, "OO", &o_order, &o_cols)) return NULL;
    Py_buffer bo, bc;
    if (PyObject_GetBuffer(o_order, &bo, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    if (PyObject_GetBuffer(o_cols, &bc, PyBUF_C_CONTIGUOUS) < 0) {
        PyBuffer_Release(&bo);
        return NULL;
    }
    PyObject *result = NULL, *out = NULL;
    const int64_t n = (int64_t)(bo.len / 8);
    if (bo.len % 8 || bc.len != bo.len * N_RUN_COLUMNS) {
        PyErr_SetString(PyExc_ValueError, "merge_runs: order int64, and 12 int64 columns of its length");
        goto done;
    }
    out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(bc.len));
    if (!out) goto done;
    const int64_t *order = bo.buf, *in = bc.buf;
    int64_t *res = (int64_t *)PyByteArray_AS_STRING(out);
    int64_t m = 0, bad = 0;
    Py_BEGIN_ALLOW_THREADS
    const int64_t *i_head = in, *i_second = in + n;
    int64_t *o_head = res, *o_second = res + n;
    for (int64_t j = 0; j < n; j++) {
        int64_t i = order[j];
        if (i < 0 || i >= n) {
            bad = 1;
            break;
        }
        if (m == 0 || i_head[i] != o_head[m - 1] || i_second[i] != o_second[m - 1]) {
            for (int c = 0; c < N_RUN_COLUMNS; c++) res[c * n + m] = in[c * n + i];
            m++;
            continue;
        }
        int64_t k = m - 1;
        for (int c = 2; c < 6; c++) res[c * n + k] += in[c * n + i]; /* records, per system, whole-second */
        for (int c = 6; c < 9; c++)                                    /* first times */
            if (in[c * n + i] < res[c * n + k]) res[c * n + k] = in[c * n + i];
        for (int c = 9; c < 12; c++) /* last times */
            if (in[c * n + i] > res[c * n + k]) res[c * n + k] = in[c * n + i];
    }
    Py_END_ALLOW_THREADS
    if (bad) {
        PyErr_SetString(PyExc_IndexError, "merge_runs: a position beyond the runs");
        goto done;
    }
    result = Py_BuildValue("(LO)", (long long)m, out);

done:
    Py_XDECREF(out);
    PyBuffer_Release(&bo);
    PyBuffer_Release(&bc);
    return result;
}

PyDoc_STRVAR(group_extremes_doc,
             "group_extremes(n, group, values, channel, wanted) -> (count, least, greatest)\n\n"
             "Per group 0..n-1, over the items whose channel is ``wanted``: how many, and the least and\n"
             "greatest value (INT64_MAX and INT64_MIN where none).  group and values: int64 per item;\n"
             "channel: int64 per item.  Outputs are int64 bytearrays of n items.");

static PyObject *group_extremes(PyObject *self, PyObject *args)
{
    long long n_groups, wanted;
    PyObject *o_group, *o_values, *o_channel;
    if (!PyArg_ParseTuple(args, "LOOOL", &n_groups, &o_group, &o_values, &o_channel, &wanted)) return NULL;
    if (n_groups < 0) {
        PyErr_SetString(PyExc_ValueError, "group_extremes: a negative number of groups");
        return NULL;
    }
    Py_buffer bg, bv, bc;
    if (PyObject_GetBuffer(o_group, &bg, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    if (PyObject_GetBuffer(o_values, &bv, PyBUF_C_CONTIGUOUS) < 0) {
        PyBuffer_Release(&bg);
        return NULL;
    }
    if (PyObject_GetBuffer(o_channel, &bc, PyBUF_C_CONTIGUOUS) < 0) {
        PyBuffer_Release(&bg);
        PyBuffer_Release(&bv);
        return NULL;
    }
    PyObject *result = NULL, *out[3] = {NULL};
    const int64_t n = (int64_t)(bg.len / 8);
    if (bg.len % 8 || bv.len != bg.len || bc.len != bg.len) {
        PyErr_SetString(PyExc_ValueError, "group_extremes: group, values and channel must be int64 of one length");
        goto done;
    }
    for (int k = 0; k < 3; k++) {
        out[k] = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n_groups * 8));
        if (!out[k]) goto done;
    }
    const int64_t *group = bg.buf, *values = bv.buf, *channel = bc.buf;
    int64_t *count = (int64_t *)PyByteArray_AS_STRING(out[0]), *least = (int64_t *)PyByteArray_AS_STRING(out[1]),
            *greatest = (int64_t *)PyByteArray_AS_STRING(out[2]);
    int bad = 0;
    Py_BEGIN_ALLOW_THREADS
    for (int64_t g = 0; g < n_groups; g++) {
        count[g] = 0;
        least[g] = INT64_MAX;
        greatest[g] = INT64_MIN;
    }
    for (int64_t i = 0; i < n; i++) {
        if (channel[i] != wanted) continue;
        int64_t g = group[i];
        if (g < 0 || g >= n_groups) {
            bad = 1;
            break;
        }
        count[g]++;
        if (values[i] < least[g]) least[g] = values[i];
        if (values[i] > greatest[g]) greatest[g] = values[i];
    }
    Py_END_ALLOW_THREADS
    if (bad) {
        PyErr_SetString(PyExc_IndexError, "group_extremes: a group beyond n");
        goto done;
    }
    result = PyTuple_Pack(3, out[0], out[1], out[2]);

done:
    for (int k = 0; k < 3; k++) Py_XDECREF(out[k]);
    PyBuffer_Release(&bg);
    PyBuffer_Release(&bv);
    PyBuffer_Release(&bc);
    return result;
}

PyDoc_STRVAR(squeeze_rows_doc,
             "squeeze_rows(rows, width) -> (text, lengths)\n\n"
             "Rows of ``width`` bytes (uint8, C order), each a text padded with 0 bytes anywhere in it: the\n"
             "texts without their 0 bytes, back to back (bytes), and each one's length (int64 bytearray).");

static PyObject *squeeze_rows(PyObject *self, PyObject *args)
{
    PyObject *o_rows;
    Py_ssize_t width;
    if (!PyArg_ParseTuple(args, "On", &o_rows, &width)) return NULL;
    if (width <= 0) {
        PyErr_SetString(PyExc_ValueError, "squeeze_rows: the width must be positive");
        return NULL;
    }
    Py_buffer b;
    if (PyObject_GetBuffer(o_rows, &b, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    PyObject *text = NULL, *lengths = NULL, *result = NULL;
    if (b.len % width) {
        PyErr_SetString(PyExc_ValueError, "squeeze_rows: the bytes are not whole rows");
        goto done;
    }
    const Py_ssize_t n = b.len / width;
    lengths = PyByteArray_FromStringAndSize(NULL, n * 8);
    text = lengths ? PyBytes_FromStringAndSize(NULL, b.len) : NULL; /* at most every byte; shrunk after */
    if (!text) goto done;
    const unsigned char *in = b.buf;
    char *out = PyBytes_AS_STRING(text);
    int64_t *len = (int64_t *)PyByteArray_AS_STRING(lengths);
    Py_ssize_t at = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t r = 0; r < n; r++) {
        const unsigned char *row = in + r * width;
        Py_ssize_t start = at;
        for (Py_ssize_t k = 0; k < width; k++) {
            out[at] = (char)row[k];
            at += row[k] != 0;
        }
        len[r] = at - start;
    }
    Py_END_ALLOW_THREADS
    if (_PyBytes_Resize(&text, at) < 0) goto done;
    result = PyTuple_Pack(2, text, lengths);

done:
    Py_XDECREF(text);
    Py_XDECREF(lengths);
    PyBuffer_Release(&b);
    return result;
}

PyDoc_STRVAR(bucket_rows_doc,
             "bucket_rows(key_head, key_second, head, time_ns) -> rows\n\n"
             "Per (head, time_ns) the first row of the keys (head, second) holding it (its second: time_ns\n"
             "floored to whole seconds), or -1.  All int64; rows: a bytearray of int64, one per item.");

static inline uint64_t bucket_hash(int64_t head, int64_t second)
{
    uint64_t h = (uint64_t)head * 0x9E3779B97F4A7C15ULL ^ (uint64_t)second * 0xC2B2AE3D27D4EB4FULL;
    return h ^ (h >> 29);
}

static PyObject *bucket_rows(PyObject *self, PyObject *args)
{
    PyObject *o[4];
    if (!PyArg_ParseTuple(args, "OOOO", &o[0], &o[1], &o[2], &o[3])) return NULL;
    Py_buffer b[4];
    int got = 0;
    PyObject *result = NULL, *out = NULL;
    int64_t *slots = NULL;
    for (; got < 4; got++)
        if (PyObject_GetBuffer(o[got], &b[got], PyBUF_C_CONTIGUOUS) < 0) goto done;
    const int64_t m = (int64_t)(b[0].len / 8), n = (int64_t)(b[2].len / 8);
    if (b[0].len % 8 || b[1].len != b[0].len || b[2].len % 8 || b[3].len != b[2].len) {
        PyErr_SetString(PyExc_ValueError, "bucket_rows: int64 keys of one length, int64 items of one length");
        goto done;
    }
    size_t n_slots = 16;
    while (n_slots < 2 * (size_t)m) n_slots <<= 1;
    slots = PyMem_RawMalloc(n_slots * sizeof(int64_t));
    out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)((n > 0 ? n : 1) * 8));
    if (!slots || !out) {
        if (!slots) PyErr_NoMemory();
        goto done;
    }
    const int64_t *k_head = b[0].buf, *k_second = b[1].buf, *p_head = b[2].buf, *p_time = b[3].buf;
    int64_t *rows = (int64_t *)PyByteArray_AS_STRING(out);
    const size_t mask = n_slots - 1;
    Py_BEGIN_ALLOW_THREADS
    memset(slots, 0xff, n_slots * sizeof(int64_t));
    for (int64_t r = 0; r < m; r++) {
        size_t i = (size_t)bucket_hash(k_head[r], k_second[r]) & mask;
        for (;; i = (i + 1) & mask) {
            int64_t e = slots[i];
            if (e < 0) {
                slots[i] = r;
                break;
            }
            if (k_head[e] == k_head[r] && k_second[e] == k_second[r]) break; /* the first row stays */
        }
    }
    for (int64_t j = 0; j < n; j++) {
        int64_t second = p_time[j] / 1000000000LL;
        if (p_time[j] % 1000000000LL < 0) second--; /* floored, as numpy's // */
        size_t i = (size_t)bucket_hash(p_head[j], second) & mask;
        int64_t row = -1;
        for (;; i = (i + 1) & mask) {
            int64_t e = slots[i];
            if (e < 0) break;
            if (k_head[e] == p_head[j] && k_second[e] == second) {
                row = e;
                break;
            }
        }
        rows[j] = row;
    }
    Py_END_ALLOW_THREADS
    result = out;
    out = NULL;

done:
    Py_XDECREF(out);
    PyMem_RawFree(slots);
    for (int k = 0; k < got; k++) PyBuffer_Release(&b[k]);
    return result;
}

static PyMethodDef methods[] = {
    {"bucket_rows", bucket_rows, METH_VARARGS, bucket_rows_doc},
    {"squeeze_rows", squeeze_rows, METH_VARARGS, squeeze_rows_doc},
    {"group_extremes", group_extremes, METH_VARARGS, group_extremes_doc},
    {"merge_runs", merge_runs, METH_VARARGS, merge_runs_doc},
    {"chunk_runs", chunk_runs, METH_VARARGS, chunk_runs_doc},
    {"head_spans", head_spans, METH_VARARGS, head_spans_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "compiled_runs", "The compiled reduction of a chunk's records to activity runs.", -1,
    methods,
};

PyMODINIT_FUNC PyInit_compiled_runs(void) { return PyModule_Create(&module); }
