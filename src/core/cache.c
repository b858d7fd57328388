/* The one cache folder of every on-disk cache (ddod's precomputation, cached
 * truth images): the host's setting (lu_set_cache_dir), else
 * $LUCENT_CACHE_DIR, else the XDG convention ($XDG_CACHE_HOME/lucent, else
 * $HOME/.cache/lucent). Never the working directory: a cache written where
 * the user happens to stand is a file nobody asked for. */
#include <lucent/core.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static char g_cache_dir[1024];

lu_result lu_set_cache_dir(const char *dir, lu_error *err) {
    if (!dir) {
        g_cache_dir[0] = '\0';
        return LU_OK;
    }
    if (!*dir || strlen(dir) >= sizeof g_cache_dir)
        return lu_fail(err, LU_ERR_INVALID_ARG, "cache folder \"%s\": empty or longer than %zu bytes", dir,
                       sizeof g_cache_dir - 1);
    snprintf(g_cache_dir, sizeof g_cache_dir, "%s", dir);
    return LU_OK;
}

lu_result lu_cache_dir(char *out, size_t cap, lu_error *err) {
    const char *env = getenv("LUCENT_CACHE_DIR"), *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    int n;
    if (g_cache_dir[0]) n = snprintf(out, cap, "%s", g_cache_dir);
    else if (env && *env) n = snprintf(out, cap, "%s", env);
    else if (xdg && xdg[0] == '/') n = snprintf(out, cap, "%s/lucent", xdg);   /* XDG: relative values are ignored */
    else if (home && *home) n = snprintf(out, cap, "%s/.cache/lucent", home);
    else
        return lu_fail(err, LU_ERR_IO, "no cache folder: set LUCENT_CACHE_DIR (or HOME, or XDG_CACHE_HOME)");
    if (n < 0 || (size_t)n >= cap) return lu_fail(err, LU_ERR_LIMIT, "cache folder path longer than %zu bytes", cap - 1);
    return LU_OK;
}

static lu_result make_dirs(const char *dir, lu_error *err) {
    char tmp[1024];
    snprintf(tmp, sizeof tmp, "%s", dir);
    for (char *p = tmp + 1; *p; p++) {
        if (*p != '/') continue;
        *p = '\0';
        if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
            return lu_fail(err, LU_ERR_IO, "%s: cannot create the cache folder: %s", tmp, strerror(errno));
        *p = '/';
    }
    if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
        return lu_fail(err, LU_ERR_IO, "%s: cannot create the cache folder: %s", tmp, strerror(errno));
    return LU_OK;
}

lu_result lu_cache_path(const char *name, bool create_dir, char *out, size_t cap, lu_error *err) {
    char dir[1024];
    lu_result r = lu_cache_dir(dir, sizeof dir, err);
    if (r == LU_OK && create_dir) r = make_dirs(dir, err);
    if (r != LU_OK) return r;
    int n = snprintf(out, cap, "%s/%s", dir, name);
    if (n < 0 || (size_t)n >= cap) return lu_fail(err, LU_ERR_LIMIT, "cache path longer than %zu bytes", cap - 1);
    return LU_OK;
}
