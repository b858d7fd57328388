/* The one cache folder of every on-disk cache (ddod's precomputation, cached
 * truth images): the host's setting (lu_set_cache_dir, lu_host.cache_dir),
 * else none. The CLI resolves $LUCENT_CACHE_DIR, else the XDG convention
 * (lu_cache_dir_conventional); never the working directory: a cache written
 * where the user happens to stand is a file nobody asked for. */
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
    /* lu_host_set with what lu_host_get answered passes the folder back. */
    if (dir == g_cache_dir) return LU_OK;
    if (!*dir || strlen(dir) >= sizeof g_cache_dir)
        return lu_fail(err, LU_ERR_INVALID_ARG, "cache folder \"%s\": empty or longer than %zu bytes", dir,
                       sizeof g_cache_dir - 1);
    snprintf(g_cache_dir, sizeof g_cache_dir, "%s", dir);
    return LU_OK;
}

const char *lu_cache_dir_copy(void) { return g_cache_dir[0] ? g_cache_dir : NULL; }

bool lu_cache_enabled(void) { return g_cache_dir[0] != '\0'; }

lu_result lu_cache_dir(char *out, size_t cap, lu_error *err) {
    if (!g_cache_dir[0])
        return lu_fail(err, LU_ERR_UNSUPPORTED, "no cache folder (lu_host.cache_dir; the CLI: LUCENT_CACHE_DIR)");
    int n = snprintf(out, cap, "%s", g_cache_dir);
    if (n < 0 || (size_t)n >= cap) return lu_fail(err, LU_ERR_LIMIT, "cache folder path longer than %zu bytes", cap - 1);
    return LU_OK;
}

lu_result lu_cache_dir_conventional(const char *lucent_cache_dir, const char *xdg_cache_home, const char *home,
                                    char *out, size_t cap, lu_error *err) {
    int n;
    if (lucent_cache_dir && *lucent_cache_dir) n = snprintf(out, cap, "%s", lucent_cache_dir);
    else if (xdg_cache_home && xdg_cache_home[0] == '/') n = snprintf(out, cap, "%s/lucent", xdg_cache_home);
    else if (home && *home) n = snprintf(out, cap, "%s/.cache/lucent", home);
    else return lu_fail(err, LU_ERR_IO, "no cache folder: set LUCENT_CACHE_DIR (or HOME, or XDG_CACHE_HOME)");
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
