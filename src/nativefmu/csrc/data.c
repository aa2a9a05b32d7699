/* Model data file of a native FMU (resources/<file>), read without Python.
 *
 * Text, one array per record:
 *
 *   jitterfmu-native-data 1
 *   <name> <rows> <cols>
 *   <rows * cols values, row-major, C99 hexadecimal floats such as 0x1.8p+1>
 *   ...
 *
 * Hexadecimal floats hold every double exactly.  They are parsed here rather than with
 * strtod, whose decimal point follows the host's locale (a tool running with
 * LC_NUMERIC=de_DE would read "0x1.8p+1" as 1).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

#define MAX_NAME 64

typedef struct {
    char name[MAX_NAME];
    size_t rows, cols;
    double *values;
} Record;

struct JfData {
    JfInstance *inst;
    char *path;
    size_t n;
    Record *records;
};

static char *read_file(JfInstance *inst, const char *path) {
    FILE *f = fopen(path, "rb");
    char *buf;
    long size;
    if (f == NULL) {
        jf_log(inst, 3, "cannot open model data %s", path);
        return NULL;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        jf_log(inst, 3, "cannot read model data %s", path);
        return NULL;
    }
    buf = (char *)jf_alloc(inst, (size_t)size + 1, 1);
    if (buf != NULL && fread(buf, 1, (size_t)size, f) != (size_t)size) {
        free(buf);
        buf = NULL;
        jf_log(inst, 3, "cannot read model data %s", path);
    }
    fclose(f);
    if (buf != NULL) buf[size] = '\0';
    return buf;
}

/* A C99 hexadecimal float ([-]0x<hex>[.<hex>]p<exp>) starting at p; *end after it, or
 * *end == p if there is none.  Exact: at most 16 significant hex digits are kept, and
 * float.hex() writes 14. */
static double parse_hex(const char *p, const char **end) {
    const char *q = p;
    uint64_t mant = 0;
    int exp2 = 0, neg = 0, digits = 0, any = 0, e = 0, eneg = 0, d;
    *end = p;
    if (*q == '-' || *q == '+') neg = *q++ == '-';
    if (q[0] != '0' || (q[1] != 'x' && q[1] != 'X')) return 0.0;
    q += 2;
    for (; (d = hexval(*q)) >= 0; q++, any = 1) {
        if (digits < 16) {
            mant = mant * 16 + (uint64_t)d;
            if (mant) digits++;
        } else {
            exp2 += 4;
        }
    }
    if (*q == '.') {
        for (q++; (d = hexval(*q)) >= 0; q++, any = 1) {
            if (digits < 16) {
                mant = mant * 16 + (uint64_t)d;
                if (mant) digits++;
                exp2 -= 4;
            }
        }
    }
    if (!any || (*q != 'p' && *q != 'P')) return 0.0;
    q++;
    if (*q == '-' || *q == '+') eneg = *q++ == '-';
    if (*q < '0' || *q > '9') return 0.0;
    for (; *q >= '0' && *q <= '9'; q++)
        if (e < 100000) e = e * 10 + (*q - '0');
    *end = q;
    return (neg ? -1.0 : 1.0) * ldexp((double)mant, exp2 + (eneg ? -e : e));
}

static const char *skip_space(const char *p) {
    while (*p == ' ' || *p == '\n' || *p == '\r' || *p == '\t') p++;
    return p;
}

static const char *read_word(const char *p, char *out, size_t n) {
    size_t k = 0;
    p = skip_space(p);
    while (*p && *p != ' ' && *p != '\n' && *p != '\r' && *p != '\t') {
        if (k + 1 < n) out[k++] = *p;
        p++;
    }
    out[k] = '\0';
    return p;
}

JfData *jf_data_open(JfInstance *inst, const char *file_name) {
    JfData *data;
    char *text, *end;
    const char *p;
    char word[MAX_NAME];
    size_t cap = 16;
    size_t len = strlen(inst->resource_dir) + strlen(file_name) + 1;

    data = (JfData *)jf_alloc(inst, 1, sizeof(JfData));
    if (data == NULL) return NULL;
    data->inst = inst;
    data->path = (char *)jf_alloc(inst, len, 1);
    data->records = (Record *)jf_alloc(inst, cap, sizeof(Record));
    if (data->path == NULL || data->records == NULL) {
        jf_data_close(data);
        return NULL;
    }
    strcpy(data->path, inst->resource_dir);
    strcat(data->path, file_name);
    text = read_file(inst, data->path);
    if (text == NULL) {
        jf_data_close(data);
        return NULL;
    }
    p = read_word(text, word, sizeof word);
    if (strcmp(word, "jitterfmu-native-data") != 0 || strtol(p, &end, 10) != 1) {
        jf_log(inst, 3, "%s is not a jitterfmu native data file of version 1", data->path);
        free(text);
        jf_data_close(data);
        return NULL;
    }
    p = end;
    for (;;) {
        Record *rec;
        size_t i, count;
        p = skip_space(p);
        if (*p == '\0') break;
        if (data->n == cap) {
            Record *more = (Record *)realloc(data->records, 2 * cap * sizeof(Record));
            if (more == NULL) goto bad;
            data->records = more;
            cap *= 2;
        }
        rec = &data->records[data->n];
        memset(rec, 0, sizeof *rec);
        p = read_word(p, rec->name, sizeof rec->name);
        rec->rows = (size_t)strtoul(p, &end, 10);
        if (end == p) goto bad;
        p = end;
        rec->cols = (size_t)strtoul(p, &end, 10);
        if (end == p) goto bad;
        p = end;
        data->n++;
        count = rec->rows * rec->cols;
        rec->values = (double *)jf_alloc(inst, count, sizeof(double));
        if (rec->values == NULL) goto bad;
        for (i = 0; i < count; i++) {
            const char *next;
            p = skip_space(p);
            rec->values[i] = parse_hex(p, &next);
            if (next == p) goto bad;
            p = next;
        }
    }
    free(text);
    return data;
bad:
    jf_log(inst, 3, "model data %s is malformed near record %lu", data->path,
           (unsigned long)data->n);
    free(text);
    jf_data_close(data);
    return NULL;
}

static Record *find(JfData *data, const char *name) {
    size_t i;
    for (i = 0; i < data->n; i++)
        if (strcmp(data->records[i].name, name) == 0) return &data->records[i];
    jf_log(data->inst, 3, "model data %s has no array %s", data->path, name);
    return NULL;
}

double *jf_data_array(JfData *data, const char *name, size_t rows, size_t cols) {
    Record *rec = find(data, name);
    double *out;
    if (rec == NULL) return NULL;
    if (rec->rows != rows || rec->cols != cols) {
        jf_log(data->inst, 3, "array %s of %s has shape (%lu, %lu); expected (%lu, %lu)", name,
               data->path, (unsigned long)rec->rows, (unsigned long)rec->cols,
               (unsigned long)rows, (unsigned long)cols);
        return NULL;
    }
    out = (double *)jf_alloc(data->inst, rows * cols, sizeof(double));
    if (out != NULL && rows * cols > 0) memcpy(out, rec->values, rows * cols * sizeof(double));
    return out;
}

int jf_data_scalar(JfData *data, const char *name, double *value) {
    Record *rec = find(data, name);
    if (rec == NULL) return JF_ERROR;
    if (rec->rows * rec->cols != 1) {
        jf_log(data->inst, 3, "array %s of %s is not a scalar", name, data->path);
        return JF_ERROR;
    }
    *value = rec->values[0];
    return JF_OK;
}

void jf_data_close(JfData *data) {
    size_t i;
    if (data == NULL) return;
    if (data->records != NULL)
        for (i = 0; i < data->n; i++) free(data->records[i].values);
    free(data->records);
    free(data->path);
    free(data);
}
