/* OpenVDB (.vdb) input through a child process.
 *
 * OpenVDB's reader is not hardened against malformed files: it trusts the
 * sizes and offsets it reads, so a hostile file can crash it. Reading such a
 * file inside the library would take the CLI, the viewer or an embedding
 * program down with it. So the library never links OpenVDB: it starts the
 * converter lucent-vdb-convert (tools/vdb_convert.cpp) with posix_spawn,
 * which reads the chosen float grid with OpenVDB, converts it with NanoVDB's
 * openToNanoVDB and writes a NanoVDB file image into an anonymous memory file
 * (memfd) that it gets as its standard output. The library then reads that
 * image through the hardened NanoVDB path (lu_grid_load_nvdb_memory), so
 * every check of .nvdb input holds for .vdb input too. A converter that dies
 * of a signal, exits with an error or writes garbage becomes an error
 * naming the .vdb file.
 *
 * Why a child process rather than a validating pre-parse: a pre-parse that
 * made OpenVDB safe would have to check every structure OpenVDB reads (grid
 * descriptors, metadata of any registered type, the tree topology, the three
 * codecs and half floats) exactly as OpenVDB interprets them: a second
 * OpenVDB reader, which would need its own hardening and would fall behind
 * the library's versions. A process boundary contains every failure of the
 * real reader, including the ones nobody has found yet. posix_spawn (not
 * fork) because the library runs worker threads and the viewer holds a GL
 * context: a forked child of a threaded process may only call
 * async-signal-safe functions until it execs, and posix_spawn execs at once.
 *
 * Where the converter is (first found wins; see docs/volumes.md):
 *   1. lu_host.vdb_converter when set (then only there);
 *   2. next to the running executable (the build tree: build/lucent and the
 *      test programs sit beside build/lucent-vdb-convert);
 *   3. <exe dir>/../<libexecdir>/lucent/ (an installed tree, relocated);
 *   4. the configured install prefix's <libexecdir>/lucent/. */
#include <lucent/grid.h>

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>


#ifndef LU_VDB_CONVERTER_NAME
#define LU_VDB_CONVERTER_NAME "lucent-vdb-convert"
#endif
#ifndef LU_INSTALL_LIBEXECDIR
#define LU_INSTALL_LIBEXECDIR "libexec"
#endif
#ifndef LU_INSTALL_FULL_LIBEXECDIR
#define LU_INSTALL_FULL_LIBEXECDIR "/usr/local/libexec"
#endif
/* What the library keeps of the converter's standard error: its one line,
 * plus room for a runaway writer's first words. */
#define VDB_MSG_CAP 600

extern char **environ;

static bool is_executable(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode) && access(path, X_OK) == 0;
}

lu_result lu_grid_vdb_converter(char *out, size_t cap, lu_error *err) {
    lu_host host;
    lu_host_get(&host);
    const char *forced = host.vdb_converter;
    if (forced) {
        if (!is_executable(forced))
            return lu_fail(err, LU_ERR_IO, "the OpenVDB converter \"%s\" (lu_host.vdb_converter) is not an executable file",
                           forced);
        snprintf(out, cap, "%s", forced);
        return LU_OK;
    }
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    char tried[3][PATH_MAX + 64];
    int count = 0;
    if (n > 0) {
        exe[n] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = '\0';
            snprintf(tried[count++], sizeof tried[0], "%s/%s", exe, LU_VDB_CONVERTER_NAME);
            snprintf(tried[count++], sizeof tried[0], "%s/../%s/lucent/%s", exe, LU_INSTALL_LIBEXECDIR,
                     LU_VDB_CONVERTER_NAME);
        }
    }
    snprintf(tried[count++], sizeof tried[0], "%s/lucent/%s", LU_INSTALL_FULL_LIBEXECDIR, LU_VDB_CONVERTER_NAME);
    for (int i = 0; i < count; i++)
        if (is_executable(tried[i])) {
            if (strlen(tried[i]) >= cap) break;
            snprintf(out, cap, "%s", tried[i]);
            return LU_OK;
        }
    return lu_fail(err, LU_ERR_UNSUPPORTED,
                   "reading .vdb needs the converter " LU_VDB_CONVERTER_NAME
                   " (built when libopenvdb-dev is installed), not found next to the program or in %s/lucent; "
                   "set lu_host.vdb_converter (the CLI: LUCENT_VDB_CONVERTER)",
                   LU_INSTALL_FULL_LIBEXECDIR);
}

/* An anonymous file the child writes the NanoVDB image to: a memfd where
 * the kernel has them, else an unlinked temporary file. Close-on-exec, so
 * other threads' children never inherit it; the spawn's dup2 onto the
 * child's standard output clears the flag there only. */
static int anon_file(void) {
#ifdef MFD_CLOEXEC
    int fd = memfd_create("lucent-vdb", MFD_CLOEXEC);
    if (fd >= 0) return fd;
#endif
    char name[] = "/tmp/lucent-vdb-XXXXXX";
    int t = mkostemp(name, O_CLOEXEC);
    if (t >= 0) unlink(name);
    return t;
}

/* Keeps the first line of what the child wrote to stderr. */
static void first_line(char *msg) {
    char *nl = strchr(msg, '\n');
    if (nl) *nl = '\0';
    size_t n = strlen(msg);
    while (n && (msg[n - 1] == '\r' || msg[n - 1] == ' ')) msg[--n] = '\0';
}

/* Runs the converter on path with its standard output on out_fd; fills msg
 * with its standard error and *status with its wait status. */
static lu_result spawn_converter(const char *conv, const char *path, const char *grid_name, int out_fd, char *msg,
                                 size_t msg_cap, int *status, lu_error *err) {
    int errpipe[2];
    if (pipe2(errpipe, O_CLOEXEC) != 0)
        return lu_fail(err, LU_ERR_IO, "%s: cannot make a pipe for the OpenVDB converter: %s", path, strerror(errno));
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t attr;
    posix_spawn_file_actions_init(&fa);
    posix_spawnattr_init(&attr);
    posix_spawn_file_actions_addopen(&fa, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&fa, out_fd, STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa, errpipe[1], STDERR_FILENO);
    /* The host may block or ignore signals (SIGPIPE, say); the converter
     * starts with none blocked and every one at its default, so a crash is
     * a crash. */
    sigset_t none, all;
    sigemptyset(&none);
    sigfillset(&all);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &all);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    char *argv[6];
    int a = 0;
    argv[a++] = (char *)conv;
    if (grid_name && *grid_name) {
        argv[a++] = (char *)"--grid";
        argv[a++] = (char *)grid_name;
    }
    argv[a++] = (char *)"--";
    argv[a++] = (char *)path;
    argv[a] = NULL;
    pid_t pid;
    int rc = posix_spawn(&pid, conv, &fa, &attr, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&attr);
    close(errpipe[1]);
    if (rc != 0) {
        close(errpipe[0]);
        return lu_fail(err, LU_ERR_IO, "%s: cannot start the OpenVDB converter %s: %s", path, conv, strerror(rc));
    }
    /* Read standard error to its end (the child may write more than a pipe
     * holds), keeping the start; then reap the child. */
    size_t used = 0;
    for (;;) {
        char chunk[512];
        ssize_t k = read(errpipe[0], chunk, sizeof chunk);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) break;
        size_t keep = used + 1 < msg_cap ? msg_cap - 1 - used : 0;
        if (keep > (size_t)k) keep = (size_t)k;
        memcpy(msg + used, chunk, keep);
        used += keep;
    }
    msg[used] = '\0';
    close(errpipe[0]);
    pid_t w;
    do w = waitpid(pid, status, 0);
    while (w < 0 && errno == EINTR);
    if (w != pid)
        return lu_fail(err, LU_ERR_IO, "%s: lost the OpenVDB converter's exit status (%s; does the program reap "
                       "children itself or ignore SIGCHLD?)", path, strerror(errno));
    return LU_OK;
}

lu_result lu_grid_load_vdb(const char *path, const char *grid_name, lu_grid *g, lu_error *err) {
    memset(g, 0, sizeof *g);
    /* Missing files and folders fail here like every loader's, before any
     * process starts. */
    void *fp;
    uint64_t in_size;
    lu_result r = lu_open_regular(path, &fp, &in_size, err);
    if (r != LU_OK) return r;
    fclose(fp);
    char conv[PATH_MAX];
    lu_error why;
    r = lu_grid_vdb_converter(conv, sizeof conv, &why);
    if (r != LU_OK) return lu_fail(err, r, "%s: %s", path, why.message);
    int out_fd = anon_file();
    if (out_fd < 0)
        return lu_fail(err, LU_ERR_IO, "%s: cannot make a memory file for the converted grid: %s", path,
                       strerror(errno));
    char msg[VDB_MSG_CAP];
    int status = 0;
    r = spawn_converter(conv, path, grid_name, out_fd, msg, sizeof msg, &status, err);
    if (r != LU_OK) {
        close(out_fd);
        return r;
    }
    first_line(msg);
    if (WIFSIGNALED(status)) {
        int sig = WTERMSIG(status);
        close(out_fd);
        return lu_fail(err, LU_ERR_FORMAT,
                       "%s: OpenVDB's reader crashed on this file (the converter %s died of signal %d, %s); the file "
                       "is malformed or not a .vdb file%s%s",
                       path, LU_VDB_CONVERTER_NAME, sig, strsignal(sig), msg[0] ? ": " : "", msg);
    }
    int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    if (code != 0) {
        close(out_fd);
        /* The converter exits with the lu_result of its failure and names
         * the file itself; anything else is a converter gone wrong. */
        size_t plen = strlen(path);
        const char *reason = strncmp(msg, path, plen) == 0 && msg[plen] == ':' ? msg + plen + 1 : msg;
        while (*reason == ' ') reason++;
        if (code > 0 && code < LU_ERR_COUNT)
            return lu_fail(err, (lu_result)code, "%s: %s", path, reason[0] ? reason : "the OpenVDB converter failed");
        return lu_fail(err, LU_ERR_IO, "%s: the OpenVDB converter %s exited with status %d%s%s", path, conv, code,
                       reason[0] ? ": " : "", reason);
    }
    struct stat st;
    if (fstat(out_fd, &st) != 0 || st.st_size <= 0) {
        close(out_fd);
        return lu_fail(err, LU_ERR_FORMAT, "%s: the OpenVDB converter %s reported success but wrote no grid", path, conv);
    }
    if ((uint64_t)st.st_size > LU_MAX_FILE_BYTES) {
        close(out_fd);
        return lu_fail(err, LU_ERR_LIMIT, "%s: the converted NanoVDB grid is %llu bytes, over the %llu-byte limit",
                       path, (unsigned long long)st.st_size, (unsigned long long)LU_MAX_FILE_BYTES);
    }
    void *image = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, out_fd, 0);
    close(out_fd);
    if (image == MAP_FAILED)
        return lu_fail(err, LU_ERR_IO, "%s: cannot map the converted grid: %s", path, strerror(errno));
    /* The converter wrote exactly the grid asked for; asking for the name
     * again catches a converter that picked another. */
    r = lu_grid_load_nvdb_memory(image, (size_t)st.st_size, path, grid_name && *grid_name ? grid_name : NULL, g, err);
    munmap(image, (size_t)st.st_size);
    return r;
}
