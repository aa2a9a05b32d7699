/* Model data file of a native FMU (resources/<file>), read without Python.
 *
 * One array per record, a text header and the values' own bits:
 *
 *   jitterfmu-native-data 2\n
 *   <name> <rows> <cols>\n
 *   <rows * cols values, row-major, IEEE 754 binary64, little-endian, 8 bytes each>
 *   ...
 *
 * Every double exactly, and no parser on the values: no locale (a tool running with
 * LC_NUMERIC=de_DE cannot change them), no rounding.  Each value is assembled from its
 * eight bytes, so a big-endian host reads the same numbers.  Everything read is checked
 * against the file's size; a non-finite value is refused (the writer never writes one).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

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

static unsigned char *read_file(JfInstance *inst, const char *path, size_t *size_out) {
    FILE *f = fopen(path, "rb");
    unsigned char *buf;
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
    buf = (unsigned char *)jf_alloc(inst, (size_t)size + 1, 1);
    if (buf != NULL && fread(buf, 1, (size_t)size, f) != (size_t)size) {
        free(buf);
        buf = NULL;
        jf_log(inst, 3, "cannot read model data %s", path);
    }
    fclose(f);
    *size_out = (size_t)size;
    return buf;
}

static const char MAGIC[] = "jitterfmu-native-data 2\n";

/* A decimal count at *p (before end), then the separator sep; 0 if there is none. */
static int read_count(const unsigned char **p, const unsigned char *end, char sep,
                      size_t *out) {
    const unsigned char *q = *p;
    size_t v = 0;
    if (q >= end || *q < '0' || *q > '9') return 0;
    for (; q < end && *q >= '0' && *q <= '9'; q++) {
        if (v > (SIZE_MAX - 9) / 10) return 0;
        v = v * 10 + (size_t)(*q - '0');
    }
    if (q >= end || *q != (unsigned char)sep) return 0;
    *out = v;
    *p = q + 1;
    return 1;
}

/* The little-endian binary64 at p. */
static double get_le_double(const unsigned char *p) {
    uint64_t u = 0;
    double d;
    int k;
    for (k = 7; k >= 0; k--) u = (u << 8) | p[k];
    memcpy(&d, &u, sizeof d);
    return d;
}

JfData *jf_data_open(JfInstance *inst, const char *file_name) {
    JfData *data;
    unsigned char *buf;
    const unsigned char *p, *end;
    size_t cap = 16, size = 0, at = 1;
    size_t len = strlen(inst->resource_dir) + strlen(file_name) + 1;
    const char *why = "malformed";

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
    buf = read_file(inst, data->path, &size);
    if (buf == NULL) {
        jf_data_close(data);
        return NULL;
    }
    if (size < sizeof MAGIC - 1 || memcmp(buf, MAGIC, sizeof MAGIC - 1) != 0) {
        jf_log(inst, 3, "%s is not a jitterfmu native data file of version 2", data->path);
        free(buf);
        jf_data_close(data);
        return NULL;
    }
    p = buf + sizeof MAGIC - 1;
    end = buf + size;
    while (p < end) {
        Record *rec;
        size_t i, k, count;
        at = data->n + 1;
        if (data->n == cap) {
            Record *more = (Record *)realloc(data->records, 2 * cap * sizeof(Record));
            if (more == NULL) goto bad;
            data->records = more;
            cap *= 2;
        }
        rec = &data->records[data->n];
        memset(rec, 0, sizeof *rec);
        for (k = 0; p < end && *p != ' ' && k + 1 < MAX_NAME; k++, p++) {
            if (*p <= ' ' || *p > '~') goto bad;
            rec->name[k] = (char)*p;
        }
        if (k == 0 || p >= end || *p != ' ') goto bad;
        p++;
        if (!read_count(&p, end, ' ', &rec->rows) || !read_count(&p, end, '\n', &rec->cols))
            goto bad;
        data->n++;
        if (rec->cols && rec->rows > SIZE_MAX / 8 / rec->cols) goto bad;
        count = rec->rows * rec->cols;
        if ((size_t)(end - p) / 8 < count) {
            why = "cut short";
            goto bad;
        }
        rec->values = (double *)jf_alloc(inst, count, sizeof(double));
        if (rec->values == NULL) goto bad;
        for (i = 0; i < count; i++, p += 8) {
            rec->values[i] = get_le_double(p);
            if (!isfinite(rec->values[i])) {
                why = "non-finite";
                goto bad;
            }
        }
    }
    free(buf);
    return data;
bad:
    jf_log(inst, 3, "model data %s is %s at array %lu", data->path, why, (unsigned long)at);
    free(buf);
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
