/* Whole-file reads, atomic writes, path helpers. */
#include <lucent/core.h>

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

lu_result lu_atomic_open(lu_atomic_file *f, const char *path, lu_error *err) {
    memset(f, 0, sizeof *f);
    if (strlen(path) >= sizeof f->final_path) return lu_fail(err, LU_ERR_INVALID_ARG, "%s: path too long", path);
    snprintf(f->final_path, sizeof f->final_path, "%s", path);
    snprintf(f->temp_path, sizeof f->temp_path, "%s.tmp.%ld", path, (long)getpid());
    f->fp = fopen(f->temp_path, "wb");
    if (!f->fp) return lu_fail(err, LU_ERR_IO, "%s: cannot open for writing: %s", path, strerror(errno));
    return LU_OK;
}

lu_result lu_atomic_commit(lu_atomic_file *f, lu_error *err) {
    FILE *fp = f->fp;
    f->fp = NULL;
    bool ok = fp && fflush(fp) == 0 && !ferror(fp);
    if (fp && fclose(fp) != 0) ok = false;
    if (!ok) {
        remove(f->temp_path);
        return lu_fail(err, LU_ERR_IO, "%s: write failed: %s", f->final_path, strerror(errno));
    }
    if (rename(f->temp_path, f->final_path) != 0) {
        int e = errno;
        remove(f->temp_path);
        return lu_fail(err, LU_ERR_IO, "%s: cannot rename temporary file into place: %s", f->final_path, strerror(e));
    }
    return LU_OK;
}

void lu_atomic_abort(lu_atomic_file *f) {
    if (f->fp) fclose(f->fp);
    f->fp = NULL;
    if (f->temp_path[0]) remove(f->temp_path);
}

lu_result lu_open_regular(const char *path, void **fp_out, uint64_t *size, lu_error *err) {
    *fp_out = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(fp);
        return lu_fail(err, LU_ERR_IO, "%s: not a regular file", path);
    }
    *fp_out = fp;
    *size = (uint64_t)st.st_size;
    return LU_OK;
}

lu_result lu_read_file(const char *path, size_t max_bytes, char **data, size_t *size, lu_error *err) {
    *data = NULL;
    *size = 0;
    FILE *fp;
    uint64_t file_size;
    lu_result r = lu_open_regular(path, (void **)&fp, &file_size, err);
    if (r != LU_OK) return r;
    if (file_size > max_bytes) {
        fclose(fp);
        return lu_fail(err, LU_ERR_LIMIT, "%s: %llu bytes exceeds the limit of %zu", path,
                       (unsigned long long)file_size, max_bytes);
    }
    size_t n = (size_t)file_size;
    char *buf = lu_malloc(n + 1);
    if (!buf) {
        fclose(fp);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory reading %zu bytes", path, n);
    }
    size_t got = fread(buf, 1, n, fp);
    fclose(fp);
    if (got != n) {
        lu_free(buf);
        return lu_fail(err, LU_ERR_IO, "%s: short read (%zu of %zu bytes)", path, got, n);
    }
    buf[n] = '\0';
    *data = buf;
    *size = n;
    return LU_OK;
}

const char *lu_path_ext(const char *path) {
    static _Thread_local char ext[16];
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash)) return "";
    size_t i = 0;
    for (const char *p = dot + 1; *p && i + 1 < sizeof ext; p++) ext[i++] = (char)tolower((unsigned char)*p);
    ext[i] = '\0';
    return ext;
}

bool lu_path_has_suffix(const char *path, const char *suffix) {
    size_t n = strlen(path), m = strlen(suffix);
    if (m > n) return false;
    for (size_t i = 0; i < m; i++)
        if (tolower((unsigned char)path[n - m + i]) != tolower((unsigned char)suffix[i])) return false;
    return true;
}

void lu_path_resolve(const char *base_file, const char *rel, char *out, size_t out_size) {
    if (!base_file || !*base_file || rel[0] == '/') {
        snprintf(out, out_size, "%s", rel);
        return;
    }
    const char *slash = strrchr(base_file, '/');
    if (!slash) {
        snprintf(out, out_size, "%s", rel);
        return;
    }
    snprintf(out, out_size, "%.*s/%s", (int)(slash - base_file), base_file, rel);
}
