/* fsutil.c -- the few file-system helpers the CLI needs. */
#if defined(__linux__) && !defined(_GNU_SOURCE)
#define _GNU_SOURCE /* syncfs */
#endif
#include "fsutil.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

static int is_directory(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

int fs_mkdir_p(const char *path, char *err, size_t err_size) {
    if (!path || !path[0]) {
        snprintf(err, err_size, "empty directory name");
        errno = EINVAL;
        return -1;
    }
    char *copy = strdup(path);
    if (!copy) {
        snprintf(err, err_size, "out of memory");
        return -1;
    }
    /* Create every prefix that ends before a '/', then the whole path. */
    int rc = 0;
    for (char *c = copy + 1; rc == 0; ++c) {
        if (*c != '/' && *c != '\0')
            continue;
        char saved = *c;
        *c = '\0';
        if (mkdir(copy, 0777) != 0 && !(errno == EEXIST && is_directory(copy))) {
            int e = errno == EEXIST ? ENOTDIR : errno;
            if (saved == '\0')
                snprintf(err, err_size, "cannot create directory %s: %s", path, strerror(e));
            else
                snprintf(err, err_size, "cannot create directory %s: %s: %s", path, copy,
                         strerror(e));
            errno = e;
            rc = -1;
        }
        *c = saved;
        if (saved == '\0')
            break;
    }
    free(copy);
    return rc;
}

int fs_mkdir_p_or_say(const char *path) {
    char err[512];
    if (fs_mkdir_p(path, err, sizeof err) == 0)
        return 0;
    fprintf(stderr, "rbcloth: %s\n", err);
    return 1;
}

char *fs_path(const char *dir, const char *stem, const char *ext) {
    size_t d = strlen(dir);
    while (d > 1 && dir[d - 1] == '/')
        --d;
    /* No separator after an empty dir ("stem.ext") or after the root ("/stem.ext"). */
    const char *sep = d == 0 || dir[d - 1] == '/' ? "" : "/";
    size_t size = d + strlen(sep) + strlen(stem) + strlen(ext) + 1;
    char *path = malloc(size);
    if (path)
        snprintf(path, size, "%.*s%s%s%s", (int)d, dir, sep, stem, ext);
    return path;
}

/* Open `path` and sync it: fsync, or with `filesystem` syncfs (Linux), which flushes
 * the whole file system that holds it. 0, or -1 with a message in err. */
static int sync_opened(const char *path, int filesystem, char *err, size_t err_size) {
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        snprintf(err, err_size, "cannot open %s to sync it: %s", path, strerror(errno));
        return -1;
    }
#ifdef __linux__
    int rc = filesystem ? syncfs(fd) : fsync(fd);
#else
    int rc = fsync(fd);
#endif
    int e = errno;
    close(fd);
    /* A file system that cannot sync a folder (EINVAL) counts as synced. */
    if (rc != 0 && (filesystem || e != EINVAL)) {
        snprintf(err, err_size, "cannot sync %s%s: %s", filesystem ? "the file system of " : "",
                 path, strerror(e));
        return -1;
    }
    return 0;
}

int fs_sync(const char *path, char *err, size_t err_size) {
    return sync_opened(path, 0, err, err_size);
}

int fs_sync_parent(const char *path, char *err, size_t err_size) {
    const char *slash = strrchr(path, '/');
    if (!slash)
        return fs_sync(".", err, err_size);
    if (slash == path)
        return fs_sync("/", err, err_size);
    char *dir = strndup(path, (size_t)(slash - path));
    if (!dir) {
        snprintf(err, err_size, "out of memory");
        return -1;
    }
    int rc = fs_sync(dir, err, err_size);
    free(dir);
    return rc;
}

int fs_sync_filesystem(const char *dir, char *err, size_t err_size) {
#ifdef __linux__
    return sync_opened(dir, 1, err, err_size);
#else
    (void)dir, (void)err, (void)err_size;
    return 1;
#endif
}

int fs_write_atomic(const char *path, const void *data, size_t size, char *err,
                    size_t err_size) {
    size_t len = strlen(path) + 32;
    char *tmp = malloc(len);
    if (!tmp) {
        snprintf(err, err_size, "out of memory");
        return -1;
    }
    snprintf(tmp, len, "%s.%ld.tmp", path, (long)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        snprintf(err, err_size, "cannot create %s: %s", tmp, strerror(errno));
        free(tmp);
        return -1;
    }
    /* The bytes reach the disk before the name does: renaming an unsynced file can
     * leave an empty one under the final name after a power loss. */
    int ok = fwrite(data, 1, size, f) == size && fflush(f) == 0 && fsync(fileno(f)) == 0;
    int e = errno;
    if (fclose(f) != 0 && ok) {
        ok = 0;
        e = errno;
    }
    if (ok && rename(tmp, path) != 0) {
        snprintf(err, err_size, "cannot rename %s to %s: %s", tmp, path, strerror(errno));
        remove(tmp);
        free(tmp);
        return -1;
    }
    if (!ok) {
        snprintf(err, err_size, "cannot write %s: %s", tmp, strerror(e));
        remove(tmp);
        free(tmp);
        return -1;
    }
    free(tmp);
    return fs_sync_parent(path, err, err_size);
}

int fs_file_crc32(const char *path, uint64_t *size, uint32_t *crc, char *err, size_t err_size) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, err_size, "cannot open %s: %s", path, strerror(errno));
        return -1;
    }
    static unsigned char buf[1 << 16];
    uLong c = crc32(0L, Z_NULL, 0);
    uint64_t n = 0;
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, f)) > 0) {
        c = crc32(c, buf, (uInt)got);
        n += got;
    }
    int bad = ferror(f);
    int e = errno;
    fclose(f);
    if (bad) {
        snprintf(err, err_size, "cannot read %s: %s", path, strerror(e));
        return -1;
    }
    *size = n;
    *crc = (uint32_t)c;
    return 0;
}

/* ------------------------------------------------------------------------- */
/* The output folder's lock                                                  */
/* ------------------------------------------------------------------------- */

/* Whether process `pid` runs (a zombie does not: it has closed its files). */
static int process_running(long pid) {
    if (pid <= 0 || kill((pid_t)pid, 0) != 0) return pid > 0 && errno == EPERM;
    char path[64], stat_line[512];
    snprintf(path, sizeof path, "/proc/%ld/stat", pid);
    FILE *f = fopen(path, "r");
    if (!f) return 1; /* no /proc: kill said it exists */
    size_t n = fread(stat_line, 1, sizeof stat_line - 1, f);
    fclose(f);
    stat_line[n] = '\0';
    const char *rp = strrchr(stat_line, ')'); /* "pid (comm) S ..." */
    return !(rp && rp[1] == ' ' && (rp[2] == 'Z' || rp[2] == 'X'));
}

/* The holder's "PID HOST OWNER" line, read from the lock file: pid 0 when there is
 * none (a file system that lost it, or a holder that wrote nothing). */
static void read_holder(int fd, long *pid, char *host, size_t host_size, char *owner,
                        size_t owner_size) {
    char text[512];
    ssize_t n = pread(fd, text, sizeof text - 1, 0);
    text[n > 0 ? n : 0] = '\0';
    char *nl = strchr(text, '\n');
    if (nl) *nl = '\0';
    *pid = 0;
    host[0] = owner[0] = '\0';
    char *end = NULL;
    long p = strtol(text, &end, 10);
    if (p <= 0 || !end || *end != ' ') return;
    *pid = p;
    size_t k = 0;
    for (++end; *end && *end != ' '; ++end)
        if (k + 1 < host_size) host[k++] = *end;
    host[k] = '\0';
    snprintf(owner, owner_size, "%s", *end ? end + 1 : "");
}

int fs_lock_dir(const char *dir, int exclusive, int create, const char *owner, double wait_s,
                int *fd_out, char *err, size_t err_size) {
    *fd_out = -1;
    err[0] = '\0';
    char *path = fs_path(dir, FS_LOCK_NAME, "");
    if (!path) {
        snprintf(err, err_size, "out of memory");
        return FS_LOCK_ERROR;
    }
    int fd = open(path, O_RDWR | O_CLOEXEC | (create ? O_CREAT : 0), 0666);
    if (fd < 0 && !create && errno == ENOENT) {
        free(path);
        return FS_LOCK_TAKEN; /* nobody ever ran a batch there */
    }
    if (fd < 0 && !create && (errno == EACCES || errno == EROFS))
        fd = open(path, O_RDONLY | O_CLOEXEC); /* flock needs no write access */
    if (fd < 0) {
        snprintf(err, err_size, "cannot open the lock file %s: %s", path, strerror(errno));
        free(path);
        return FS_LOCK_ERROR;
    }
    char me[256] = "";
    gethostname(me, sizeof me - 1);
    const int op = (exclusive ? LOCK_EX : LOCK_SH) | LOCK_NB;
    struct timespec nap = {0, 20 * 1000 * 1000}, t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        if (flock(fd, op) == 0) break;
        if (errno == EINTR) continue;
        if (errno != EWOULDBLOCK) {
            /* No locks on this file system (some network mounts): go on, unprotected. */
            snprintf(err, err_size, "cannot lock %s (%s): nothing stops a second batch from "
                     "writing into %s at the same time", path, strerror(errno), dir);
            break;
        }
        long pid;
        char host[256], held_by[256];
        read_holder(fd, &pid, host, sizeof host, held_by, sizeof held_by);
        const int here = pid > 0 && strcmp(host, me) == 0;
        const int gone = here && !process_running(pid);
        struct timespec t;
        clock_gettime(CLOCK_MONOTONIC, &t);
        const double waited =
            (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec);
        /* The holder was killed and its workers, which share the lock, are exiting; or
         * a holder has just taken it and not yet written its pid. */
        if ((gone && waited < wait_s) || (pid == 0 && waited < 0.2)) {
            nanosleep(&nap, NULL);
            continue;
        }
        int len = pid > 0 ? snprintf(err, err_size, "%s is in use by another rbcloth (pid %ld on "
                                     "%s%s%s)", dir, pid, host, held_by[0] ? ": " : "", held_by)
                          : snprintf(err, err_size, "%s is in use by another rbcloth", dir);
        if (len >= 0 && (size_t)len < err_size && gone)
            snprintf(err + len, err_size - (size_t)len,
                     ", which has exited, but processes it started still hold %s after %.0f s; "
                     "wait for them to end or choose another --out", path, wait_s);
        else if (len >= 0 && (size_t)len < err_size)
            snprintf(err + len, err_size - (size_t)len,
                     ", which holds %s; wait for it to end or choose another --out", path);
        close(fd);
        free(path);
        return FS_LOCK_BUSY;
    }
    if (owner) {
        char line[512];
        int n = snprintf(line, sizeof line, "%ld %s %s\n", (long)getpid(), me[0] ? me : "?", owner);
        if (ftruncate(fd, 0) != 0 || pwrite(fd, line, (size_t)n, 0) != n) {
            /* Only the refusal message of another process reads it. */
        }
    }
    free(path);
    *fd_out = fd;
    return FS_LOCK_TAKEN;
}
