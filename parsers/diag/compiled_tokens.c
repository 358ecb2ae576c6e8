/* The compiled tokenizer of diagnostic records: one pass over a chunk.
 *
 * It does what parsers/diag/tokens_numpy.py's tokenize_numpy does, rule for rule (the
 * pure path is the reference; tests/test_diag_compiled.py checks both give the
 * same tokens, records and rejections): cut the chunk into lines, trim CR and
 * trailing blanks, find the last three tabs of each line of at least 64 bytes,
 * dictionary-encode the register and value spans in order of first appearance,
 * and read the time with its fraction digits.  The work runs without the GIL;
 * only the allocation of the outputs and the dictionaries' bytes objects hold it.
 *
 * Outputs are bytearrays (wrapped by numpy in Python), so the build needs the
 * Python headers only.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#define MIN_FAST_LINE 64
#define VIEW_INLINE_MAX 12
#define NS_PER_S 1000000000LL

typedef struct {
    int64_t *slots; /* entry index, or -1 */
    size_t mask;
    int64_t *off;
    int64_t *len;
    uint64_t *hash;
    size_t n, cap;
} SpanDict;

static inline uint64_t load64_partial(const unsigned char *p, int64_t n)
{
    uint64_t v = 0;
    memcpy(&v, p, (size_t)n);
    return v;
}

static uint64_t hash_span(const unsigned char *p, int64_t n)
{
    uint64_t h = 0x9E3779B97F4A7C15ULL ^ (uint64_t)n;
    int64_t i = 0;
    for (; i + 8 <= n; i += 8) {
        uint64_t w;
        memcpy(&w, p + i, 8);
        h = (h ^ w) * 0xff51afd7ed558ccdULL;
        h ^= h >> 32;
    }
    h = (h ^ load64_partial(p + i, n - i)) * 0xc4ceb9fe1a85ec53ULL;
    h ^= h >> 29;
    return h;
}

static int dict_init(SpanDict *d, size_t cap)
{
    size_t slots = 64;
    while (slots < 2 * cap) slots <<= 1;
    d->slots = PyMem_RawMalloc(slots * sizeof(int64_t));
    d->off = PyMem_RawMalloc(cap * sizeof(int64_t));
    d->len = PyMem_RawMalloc(cap * sizeof(int64_t));
    d->hash = PyMem_RawMalloc(cap * sizeof(uint64_t));
    d->mask = slots - 1;
    d->n = 0;
    d->cap = cap;
    if (!d->slots || !d->off || !d->len || !d->hash) return -1;
    memset(d->slots, 0xff, slots * sizeof(int64_t));
    return 0;
}

static void dict_free(SpanDict *d)
{
    PyMem_RawFree(d->slots);
    PyMem_RawFree(d->off);
    PyMem_RawFree(d->len);
    PyMem_RawFree(d->hash);
}

/* The index of the span buf[off:off+len] (a new one: the next index), or -1 on no memory. */
static int64_t dict_index(SpanDict *d, const unsigned char *buf, int64_t off, int64_t len)
{
    uint64_t h = hash_span(buf + off, len);
    size_t i = (size_t)h & d->mask;
    for (;;) {
        int64_t e = d->slots[i];
        if (e < 0) break;
        if (d->hash[e] == h && d->len[e] == len && memcmp(buf + d->off[e], buf + off, (size_t)len) == 0) return e;
        i = (i + 1) & d->mask;
    }
    if (d->n == d->cap) { /* the entries are sized for every line of the chunk: never reached */
        return -1;
    }
    int64_t e = (int64_t)d->n++;
    d->off[e] = off;
    d->len[e] = len;
    d->hash[e] = h;
    d->slots[i] = e;
    if (d->n * 2 > d->mask + 1) { /* grow: rehash into twice the slots */
        size_t slots = (d->mask + 1) * 2;
        int64_t *ns = PyMem_RawMalloc(slots * sizeof(int64_t));
        if (!ns) return -1;
        memset(ns, 0xff, slots * sizeof(int64_t));
        for (size_t k = 0; k < d->n; k++) {
            size_t j = (size_t)d->hash[k] & (slots - 1);
            while (ns[j] >= 0) j = (j + 1) & (slots - 1);
            ns[j] = (int64_t)k;
        }
        PyMem_RawFree(d->slots);
        d->slots = ns;
        d->mask = slots - 1;
    }
    return e;
}

/* The offset of the last tab in buf[lo:hi], or -1. */
static inline int64_t last_tab(const unsigned char *buf, int64_t lo, int64_t hi)
{
    for (int64_t k = hi - 1; k >= lo; k--)
        if (buf[k] == 9) return k;
    return -1;
}

static inline int is_digit(unsigned char c) { return c >= '0' && c <= '9'; }

static PyObject *dict_list(const SpanDict *d, const unsigned char *buf)
{
    PyObject *list = PyList_New((Py_ssize_t)d->n);
    if (!list) return NULL;
    for (size_t k = 0; k < d->n; k++) {
        PyObject *b = PyBytes_FromStringAndSize((const char *)buf + d->off[k], (Py_ssize_t)d->len[k]);
        if (!b) {
            Py_DECREF(list);
            return NULL;
        }
        PyList_SET_ITEM(list, (Py_ssize_t)k, b);
    }
    return list;
}

#define OUT(i) ((void *)PyByteArray_AS_STRING(out[i]))

PyDoc_STRVAR(tokenize_doc,
             "tokenize(data) -> (n_fast, starts, ends, blank, fast, reg_idx, reg_dict, val_idx, val_dict,\n"
             "                   tod_ns, subsecond, time_ok)\n\n"
             "Cut a chunk that ends with a newline into lines and spans.  The arrays are bytearrays: int64\n"
             "(starts, ends, fast, reg_idx, val_idx, tod_ns) or bool (blank, subsecond, time_ok); those\n"
             "per fast line hold n_fast valid items.");

static PyObject *tokenize(PyObject *self, PyObject *arg)
{
    Py_buffer view;
    if (PyObject_GetBuffer(arg, &view, PyBUF_SIMPLE) < 0) return NULL;
    const unsigned char *buf = view.buf;
    int64_t size = (int64_t)view.len;
    if (size == 0 || buf[size - 1] != '\n') {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_ValueError, "tokenize: the data must end with a newline");
        return NULL;
    }
    int64_t n_lines = 0;
    /* Counted without the GIL too: a pass over the whole chunk, which the reading thread would wait for. */
    Py_BEGIN_ALLOW_THREADS
    for (const unsigned char *p = buf, *end = buf + size; p < end; n_lines++) {
        const unsigned char *q = memchr(p, '\n', (size_t)(end - p));
        p = q + 1;
    }
    Py_END_ALLOW_THREADS
    /* starts, ends, blank, fast, reg_idx, val_idx, tod_ns, subsecond, time_ok */
    static const int widths[9] = {8, 8, 1, 8, 8, 8, 8, 1, 1};
    PyObject *out[9] = {NULL};
    for (int i = 0; i < 9; i++) {
        out[i] = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n_lines * widths[i]));
        if (!out[i]) goto fail;
    }
    int64_t *starts = OUT(0), *ends = OUT(1), *fast = OUT(3), *reg_idx = OUT(4), *val_idx = OUT(5),
            *tod_ns = OUT(6);
    char *blank = OUT(2), *subsecond = OUT(7), *time_ok = OUT(8);
    SpanDict reg, val;
    memset(&reg, 0, sizeof reg);
    memset(&val, 0, sizeof val);
    int64_t n_fast = 0;
    int no_memory = 0;

    Py_BEGIN_ALLOW_THREADS
    if (dict_init(&reg, (size_t)n_lines + 1) < 0 || dict_init(&val, (size_t)n_lines + 1) < 0) {
        no_memory = 1;
    }
    else {
        int64_t s = 0;
        for (int64_t i = 0; i < n_lines; i++) {
            const unsigned char *nl = memchr(buf + s, '\n', (size_t)(size - s));
            int64_t e = (int64_t)(nl - buf);
            int64_t next = e + 1;
            /* CR and trailing blanks: at most four bytes, as the vectorized path trims. */
            for (int k = 0; k < 4 && e > s && (buf[e - 1] == 13 || buf[e - 1] == 32); k++) e--;
            int64_t st = s;
            starts[i] = st;
            ends[i] = e;
            blank[i] = e == st;
            s = next;
            if (e - st < MIN_FAST_LINE) continue;
            /* The tab before Time: whole-second and millisecond times by direct look, else the last
               tab of the line's last 24 bytes. */
            int64_t t10 = buf[e - 14] == 9 ? e - 14 : buf[e - 18] == 9 ? e - 18 : last_tab(buf, e - 24, e);
            if (t10 < 0 || buf[t10 - 16] != 9) continue; /* the tab before Date: Date:YYYY-MM-DD */
            int64_t t9 = t10 - 16;
            int64_t t8 = last_tab(buf, t9 - 16, t9); /* the tab before Data */
            if (!(t8 - st > VIEW_INLINE_MAX && e - t10 >= 14)) continue;
            int64_t j = n_fast++;
            fast[j] = i;
            int64_t r = dict_index(&reg, buf, st, t8 - st);
            int64_t v = dict_index(&val, buf, t8 + 1, t10 - t8 - 1);
            if (r < 0 || v < 0) {
                no_memory = 1;
                break;
            }
            reg_idx[j] = r;
            val_idx[j] = v;

            /* Time: "Time:HH:MM:SS" plus an optional ".f" or ",f" of 1-9 digits (rules of fields.parse_time). */
            int64_t ts = t10 + 1, tlen = e - ts;
            const unsigned char *h = buf + ts + 5;
            int ok = memcmp(buf + ts, "Time:", 5) == 0 && (tlen == 13 || (tlen >= 15 && tlen <= 23)) &&
                     is_digit(h[0]) && is_digit(h[1]) && h[2] == ':' && is_digit(h[3]) && is_digit(h[4]) &&
                     h[5] == ':' && is_digit(h[6]) && is_digit(h[7]);
            int64_t hh = (h[0] - '0') * 10 + (h[1] - '0');
            int64_t mm = (h[3] - '0') * 10 + (h[4] - '0');
            int64_t ss = (h[6] - '0') * 10 + (h[7] - '0');
            ok = ok && hh < 24 && mm < 60 && ss < 60;
            int64_t tod = ((hh * 60 + mm) * 60 + ss) * NS_PER_S;
            int64_t n_frac = (tlen >= 15 && tlen <= 23) ? tlen - 14 : 0;
            if (n_frac > 0) {
                ok = ok && (buf[ts + 13] == '.' || buf[ts + 13] == ',');
                int64_t frac = 0;
                for (int64_t k = e - n_frac; k < e; k++) {
                    ok = ok && is_digit(buf[k]);
                    frac = frac * 10 + (buf[k] - '0');
                }
                for (int64_t k = n_frac; k < 9; k++) frac *= 10;
                tod += frac;
            }
            tod_ns[j] = ok ? tod : 0;
            subsecond[j] = n_frac > 0;
            time_ok[j] = (char)ok;
        }
    }
    Py_END_ALLOW_THREADS

    if (no_memory) {
        dict_free(&reg);
        dict_free(&val);
        PyErr_NoMemory();
        goto fail;
    }
    PyObject *reg_list = dict_list(&reg, buf);
    PyObject *val_list = reg_list ? dict_list(&val, buf) : NULL;
    dict_free(&reg);
    dict_free(&val);
    PyBuffer_Release(&view);
    if (!val_list) {
        Py_XDECREF(reg_list);
        for (int i = 0; i < 9; i++) Py_DECREF(out[i]);
        return NULL;
    }
    return Py_BuildValue("(LNNNNNNNNNNN)", (long long)n_fast, out[0], out[1], out[2], out[3], out[4], reg_list,
                         out[5], val_list, out[6], out[7], out[8]);

fail:
    for (int i = 0; i < 9; i++) Py_XDECREF(out[i]);
    PyBuffer_Release(&view);
    return NULL;
}


PyDoc_STRVAR(gather_records_doc,
             "gather_records(reg_lut, reg_idx, val_idx, val_cols, val_ok, time_ok, tod_ns, subsecond, fast)\n"
             "    -> (n_good, register_id, time_ns, value, data_code, data_kind, subsecond, line, bad)\n\n"
             "The record columns of a chunk's good fast lines: register and value spans valid (reg_lut int32\n"
             ">= 0 per register span, val_ok bool per value span) and time read (time_ok).  reg_idx, val_idx,\n"
             "tod_ns, fast: int64 per fast line; subsecond: bool per fast line; val_cols: int64 rows (data\n"
             "code, value, kind code, day ns) per value span, C order.  Outputs are bytearrays of one item per\n"
             "fast line (int32, int64, int64, int32, int8, bool, int64), the first n_good valid; bad: int64\n"
             "positions of the other fast lines, in order.");

static PyObject *gather_records(PyObject *self, PyObject *args)
{
    enum { N_IN = 9, N_OUT = 8 };
    PyObject *o[N_IN];
    if (!PyArg_ParseTuple(args, "OOOOOOOOO", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8]))
        return NULL;
    Py_buffer b[N_IN];
    static const Py_ssize_t sizes[N_IN] = {4, 8, 8, 8, 1, 1, 8, 1, 8};
    int got = 0;
    PyObject *result = NULL;
    PyObject *out[N_OUT] = {NULL};
    for (; got < N_IN; got++) {
        if (PyObject_GetBuffer(o[got], &b[got], PyBUF_C_CONTIGUOUS) < 0) goto done;
        if (b[got].len % sizes[got] != 0) {
            got++;
            PyErr_SetString(PyExc_ValueError, "gather_records: an array of the wrong item size");
            goto done;
        }
    }
    const int64_t n_reg = (int64_t)(b[0].len / 4), n = (int64_t)(b[1].len / 8), m = (int64_t)b[4].len;
    if (b[2].len / 8 != n || b[5].len != n || b[6].len / 8 != n || b[7].len != n || b[8].len / 8 != n ||
        b[3].len / 8 != 4 * m) {
        PyErr_SetString(PyExc_ValueError, "gather_records: the columns differ in length");
        goto done;
    }
    const int32_t *reg_lut = b[0].buf;
    const int64_t *reg_idx = b[1].buf, *val_idx = b[2].buf, *val_cols = b[3].buf, *tod_ns = b[6].buf,
                  *fast = b[8].buf;
    const unsigned char *val_ok = b[4].buf, *time_ok = b[5].buf, *subsecond = b[7].buf;
    static const int widths[N_OUT] = {4, 8, 8, 4, 1, 1, 8, 8};
    for (int k = 0; k < N_OUT; k++) {
        out[k] = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n * widths[k]));
        if (!out[k]) goto done;
    }
    int32_t *rid = (int32_t *)PyByteArray_AS_STRING(out[0]), *code = (int32_t *)PyByteArray_AS_STRING(out[3]);
    int64_t *time_out = (int64_t *)PyByteArray_AS_STRING(out[1]), *value = (int64_t *)PyByteArray_AS_STRING(out[2]),
            *line = (int64_t *)PyByteArray_AS_STRING(out[6]), *bad = (int64_t *)PyByteArray_AS_STRING(out[7]);
    int8_t *kind = (int8_t *)PyByteArray_AS_STRING(out[4]);
    char *sub = PyByteArray_AS_STRING(out[5]);
    int64_t n_good = 0, n_bad = 0, out_of_range = 0;
    Py_BEGIN_ALLOW_THREADS
    const int64_t *v_code = val_cols, *v_value = val_cols + m, *v_kind = val_cols + 2 * m, *v_day = val_cols + 3 * m;
    for (int64_t i = 0; i < n; i++) {
        int64_t r = reg_idx[i], v = val_idx[i];
        if (r < 0 || r >= n_reg || v < 0 || v >= m) {
            out_of_range = 1;
            break;
        }
        if (reg_lut[r] < 0 || !val_ok[v] || !time_ok[i]) {
            bad[n_bad++] = i;
            continue;
        }
        int64_t j = n_good++;
        rid[j] = reg_lut[r];
        time_out[j] = v_day[v] + tod_ns[i];
        value[j] = v_value[v];
        code[j] = (int32_t)v_code[v];
        kind[j] = (int8_t)v_kind[v];
        sub[j] = (char)subsecond[i];
        line[j] = fast[i];
    }
    Py_END_ALLOW_THREADS
    if (out_of_range) {
        PyErr_SetString(PyExc_IndexError, "gather_records: a span index beyond its dictionary");
        goto done;
    }
    result = Py_BuildValue("(LOOOOOOOO)", (long long)n_good, out[0], out[1], out[2], out[3], out[4], out[5],
                           out[6], out[7]);

done:
    for (int k = 0; k < N_OUT; k++) Py_XDECREF(out[k]);
    for (int k = 0; k < got; k++) PyBuffer_Release(&b[k]);
    return result;
}

static PyMethodDef methods[] = {
    {"tokenize", tokenize, METH_O, tokenize_doc},
    {"gather_records", gather_records, METH_VARARGS, gather_records_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "compiled_tokens", "The compiled tokenizer of diagnostic records.", -1, methods,
};

PyMODINIT_FUNC PyInit_compiled_tokens(void) { return PyModule_Create(&module); }
