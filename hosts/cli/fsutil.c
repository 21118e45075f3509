/* fsutil.c -- the few file-system helpers the CLI needs. */
#include "fsutil.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

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

int fs_write_atomic(const char *path, const void *data, size_t size, char *err,
                    size_t err_size) {
    size_t len = strlen(path) + sizeof ".tmp";
    char *tmp = malloc(len);
    if (!tmp) {
        snprintf(err, err_size, "out of memory");
        return -1;
    }
    snprintf(tmp, len, "%s.tmp", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        snprintf(err, err_size, "cannot create %s: %s", tmp, strerror(errno));
        free(tmp);
        return -1;
    }
    int ok = fwrite(data, 1, size, f) == size;
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
    return 0;
}
