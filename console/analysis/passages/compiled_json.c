/* The compiled encoder of passages as JSON objects: what console/analysis/passages/json_text.py's
 * encode_objects writes (the numpy path is the reference; tests/test_json_compiled.py checks both give the
 * same bytes), formatted here from the numeric columns in one pass per passage without the GIL, so the
 * spool's encoding thread does not hold up the main thread.
 *
 * The caller (json_text.py) does the checks once per batch or per distinct value (floats it covers, texts
 * that need no escaping) and passes a list of fields, each (kind, key, buffers...); the key holds what
 * comes before the value ('{"device_id":' or ',"records":').  Outputs are bytearrays.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#define MAX_FIELDS 40
#define NS_PER_S 1000000000LL
#define NS_PER_DAY 86400000000000LL

enum { K_INT, K_FLOAT, K_TEXT, K_ISO, K_BOOL, K_AXLES };

typedef struct {
    int kind;
    Py_buffer key, a, b, c;
    int has_b, has_c;
} Field;

typedef struct {
    char *p;
    size_t len, cap;
} Out;

static int reserve(Out *o, size_t more)
{
    if (o->len + more <= o->cap) return 0;
    size_t cap = o->cap ? o->cap : 4096;
    while (cap < o->len + more) cap *= 2;
    char *p = realloc(o->p, cap);
    if (!p) return -1;
    o->p = p;
    o->cap = cap;
    return 0;
}

/* Callers reserve first: every writer below needs at most 64 bytes, a key or a text its own length. */
static inline void put(Out *o, const void *s, size_t n)
{
    memcpy(o->p + o->len, s, n);
    o->len += n;
}

static inline void put_u64(Out *o, uint64_t u)
{
    char tmp[24];
    int i = 24;
    do {
        tmp[--i] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    put(o, tmp + i, (size_t)(24 - i));
}

static inline void put_digits(Out *o, uint64_t u, int width)
{
    char *d = o->p + o->len;
    for (int i = width - 1; i >= 0; i--) {
        d[i] = (char)('0' + u % 10);
        u /= 10;
    }
    o->len += (size_t)width;
}

static inline void put_int(Out *o, int64_t v)
{
    if (v < 0) {
        put(o, "-", 1);
        put_u64(o, (uint64_t)0 - (uint64_t)v);
    } else {
        put_u64(o, (uint64_t)v);
    }
}

/* ultrajson's fixed point with ten decimals, as json_text._float_tokens computes it (the caller has
 * checked the value is covered: finite, below 1e16-1, zero or at least 1e-15). */
static inline void put_float(Out *o, double v)
{
    if (isnan(v)) {
        put(o, "null", 4);
        return;
    }
    double a = fabs(v);
    uint64_t whole = (uint64_t)a;
    volatile double tmp = (a - (double)whole) * 1e10; /* volatile: no fused or wider arithmetic */
    uint64_t frac = (uint64_t)tmp;
    double diff = tmp - (double)frac;
    if (diff > 0.5 || (diff == 0.5 && (frac == 0 || (frac & 1)))) frac++;
    if (frac >= 10000000000ULL) {
        frac = 0;
        whole++;
    }
    if (v < 0) put(o, "-", 1);
    put_u64(o, whole);
    put(o, ".", 1);
    if (frac == 0) {
        put(o, "0", 1);
        return;
    }
    int width = 10;
    while (frac % 10 == 0) {
        frac /= 10;
        width--;
    }
    put_digits(o, frac, width);
}

/* Howard Hinnant's days_from_civil inverted: the proleptic Gregorian date of a day since 1970-01-01. */
static inline void put_date(Out *o, int64_t z)
{
    z += 719468;
    int64_t era = (z >= 0 ? z : z - 146096) / 146097;
    int64_t doe = z - era * 146097;
    int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    int64_t y = yoe + era * 400;
    int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    int64_t mp = (5 * doy + 2) / 153;
    int64_t d = doy - (153 * mp + 2) / 5 + 1;
    int64_t m = mp < 10 ? mp + 3 : mp - 9;
    y += (m <= 2);
    put_digits(o, (uint64_t)y, 4);
    put(o, "-", 1);
    put_digits(o, (uint64_t)m, 2);
    put(o, "-", 1);
    put_digits(o, (uint64_t)d, 2);
}

static inline void put_iso(Out *o, int64_t ns)
{
    int64_t day = ns / NS_PER_DAY, tod = ns % NS_PER_DAY;
    if (tod < 0) {
        tod += NS_PER_DAY;
        day--;
    }
    int64_t secs = tod / NS_PER_S, frac = tod % NS_PER_S;
    put(o, "\"", 1);
    put_date(o, day);
    put(o, "T", 1);
    put_digits(o, (uint64_t)(secs / 3600), 2);
    put(o, ":", 1);
    put_digits(o, (uint64_t)(secs / 60 % 60), 2);
    put(o, ":", 1);
    put_digits(o, (uint64_t)(secs % 60), 2);
    put(o, ".", 1);
    /* Milliseconds always; micro- and nanoseconds only where the time has them (timefmt.iso). */
    if (frac % 1000000 == 0)
        put_digits(o, (uint64_t)(frac / 1000000), 3);
    else if (frac % 1000 == 0)
        put_digits(o, (uint64_t)(frac / 1000), 6);
    else
        put_digits(o, (uint64_t)frac, 9);
    put(o, "Z\"", 2);
}

static void release(Field *f, int n)
{
    for (int i = 0; i < n; i++) {
        PyBuffer_Release(&f[i].key);
        PyBuffer_Release(&f[i].a);
        if (f[i].has_b) PyBuffer_Release(&f[i].b);
        if (f[i].has_c) PyBuffer_Release(&f[i].c);
    }
}

static int get(PyObject *o, Py_buffer *b)
{
    return PyObject_GetBuffer(o, b, PyBUF_C_CONTIGUOUS);
}

/* Encode passages 0…n-1; 0 on success, -1 out of memory. */
static int encode(Field *f, int nf, Py_ssize_t n, const char *close, Py_ssize_t close_len, Out *o, int64_t *lengths)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        size_t begin = o->len;
        for (int k = 0; k < nf; k++) {
            const Field *fk = &f[k];
            if (reserve(o, (size_t)fk->key.len + 64)) return -1;
            put(o, fk->key.buf, (size_t)fk->key.len);
            switch (fk->kind) {
            case K_INT: {
                const uint8_t *null = fk->has_b ? fk->b.buf : NULL;
                if (null && null[i])
                    put(o, "null", 4);
                else
                    put_int(o, ((const int64_t *)fk->a.buf)[i]);
                break;
            }
            case K_FLOAT:
                put_float(o, ((const double *)fk->a.buf)[i]);
                break;
            case K_TEXT: {
                int64_t code = ((const int64_t *)fk->a.buf)[i];
                const int64_t *offsets = fk->c.buf;
                size_t len = (size_t)(offsets[code + 1] - offsets[code]);
                if (reserve(o, len)) return -1;
                put(o, (const char *)fk->b.buf + offsets[code], len);
                break;
            }
            case K_ISO:
                if (((const uint8_t *)fk->b.buf)[i])
                    put_iso(o, ((const int64_t *)fk->a.buf)[i]);
                else
                    put(o, "null", 4);
                break;
            case K_BOOL:
                if (((const uint8_t *)fk->a.buf)[i])
                    put(o, "true", 4);
                else
                    put(o, "false", 5);
                break;
            case K_AXLES: {
                int64_t lo = ((const int64_t *)fk->b.buf)[i], hi = ((const int64_t *)fk->c.buf)[i];
                if (hi <= lo) {
                    put(o, "null", 4);
                    break;
                }
                const double *speeds = fk->a.buf;
                for (int64_t j = lo; j < hi; j++) {
                    if (reserve(o, 64)) return -1;
                    put(o, j == lo ? "[" : ",", 1);
                    put_float(o, speeds[j]);
                }
                put(o, "]", 1);
                break;
            }
            }
        }
        if (reserve(o, (size_t)close_len)) return -1;
        put(o, close, (size_t)close_len);
        lengths[i] = (int64_t)(o->len - begin);
    }
    return 0;
}

PyDoc_STRVAR(encode_objects_doc,
             "encode_objects(n, fields, close) -> (text, lengths)\n\n"
             "fields: tuples (kind, key, a[, b[, c]]): 0 int (int64, null uint8 or None), 1 float (float64,\n"
             "NaN null), 2 text (int64 codes, the texts' bytes back to back, int64 offsets), 3 ISO time\n"
             "(int64 ns, present uint8), 4 bool (uint8), 5 per-axle list (float64 speeds, int64 start,\n"
             "int64 stop).  text: the objects back to back; lengths: int64 per object.");

static PyObject *encode_objects(PyObject *self, PyObject *args)
{
    Py_ssize_t n;
    PyObject *fields;
    Py_buffer close;
    if (!PyArg_ParseTuple(args, "nO!y*", &n, &PyList_Type, &fields, &close)) return NULL;
    Py_ssize_t nf = PyList_GET_SIZE(fields);
    if (nf > MAX_FIELDS) {
        PyBuffer_Release(&close);
        PyErr_SetString(PyExc_ValueError, "encode_objects: too many fields");
        return NULL;
    }
    Field f[MAX_FIELDS];
    memset(f, 0, sizeof f);
    int got = 0;
    for (; got < nf; got++) {
        PyObject *t = PyList_GET_ITEM(fields, got);
        PyObject *b = Py_None, *c = Py_None, *a;
        PyObject *key;
        if (!PyArg_ParseTuple(t, "iOO|OO", &f[got].kind, &key, &a, &b, &c)) goto fail;
        if (get(key, &f[got].key) < 0) goto fail;
        if (get(a, &f[got].a) < 0) {
            PyBuffer_Release(&f[got].key);
            goto fail;
        }
        if (b != Py_None) {
            if (get(b, &f[got].b) < 0) {
                PyBuffer_Release(&f[got].key);
                PyBuffer_Release(&f[got].a);
                goto fail;
            }
            f[got].has_b = 1;
        }
        if (c != Py_None) {
            if (get(c, &f[got].c) < 0) {
                PyBuffer_Release(&f[got].key);
                PyBuffer_Release(&f[got].a);
                if (f[got].has_b) PyBuffer_Release(&f[got].b);
                goto fail;
            }
            f[got].has_c = 1;
        }
        int kind = f[got].kind;
        int need_b = kind == K_TEXT || kind == K_ISO || kind == K_AXLES, need_c = kind == K_TEXT || kind == K_AXLES;
        Py_ssize_t item = kind == K_BOOL ? 1 : 8;
        if (kind < K_INT || kind > K_AXLES || (need_b && !f[got].has_b) || (need_c && !f[got].has_c) ||
            (kind != K_AXLES && f[got].a.len < n * item)) {
            got++;
            PyErr_SetString(PyExc_ValueError, "encode_objects: a field's buffers do not fit its kind");
            goto fail;
        }
    }
    int64_t *lengths = PyMem_RawMalloc((size_t)(n ? n : 1) * sizeof(int64_t));
    Out o = {NULL, 0, 0};
    if (!lengths) {
        PyErr_NoMemory();
        goto fail;
    }
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = encode(f, (int)nf, n, close.buf, close.len, &o, lengths);
    Py_END_ALLOW_THREADS
    release(f, got);
    PyBuffer_Release(&close);
    if (rc < 0) {
        free(o.p);
        PyMem_RawFree(lengths);
        return PyErr_NoMemory();
    }
    PyObject *text = PyByteArray_FromStringAndSize(o.p ? o.p : "", (Py_ssize_t)o.len);
    free(o.p);
    PyObject *lens = text ? PyByteArray_FromStringAndSize((const char *)lengths, n * (Py_ssize_t)sizeof(int64_t)) : NULL;
    PyMem_RawFree(lengths);
    if (!lens) {
        Py_XDECREF(text);
        return NULL;
    }
    return Py_BuildValue("(NN)", text, lens);
fail:
    release(f, got);
    PyBuffer_Release(&close);
    return NULL;
}

static PyMethodDef methods[] = {
    {"encode_objects", encode_objects, METH_VARARGS, encode_objects_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "compiled_json",
                                    "The passages' JSON objects, formatted without the GIL.", -1, methods};

PyMODINIT_FUNC PyInit_compiled_json(void) { return PyModule_Create(&module); }
