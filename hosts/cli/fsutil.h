/* fsutil.h -- the few file-system helpers the CLI needs. */
#ifndef RBC_CLI_FSUTIL_H
#define RBC_CLI_FSUTIL_H

#include <stddef.h>
#include <stdint.h>

/// Create `path` and its missing parents (mkdir -p). Returns 0, or -1 with errno
/// set and a message in err.
int fs_mkdir_p(const char *path, char *err, size_t err_size);

/// fs_mkdir_p for a command: 0, or 1 (its exit code) after "rbcloth: <why>" on
/// stderr.
int fs_mkdir_p_or_say(const char *path);

/// malloc'd "dir/stem.ext" (no doubled '/'), or NULL when out of memory.
char *fs_path(const char *dir, const char *stem, const char *ext);

/// Write `size` bytes to `path` atomically and durably: "<path>.<pid>.tmp" (this
/// process's own name, so that two writers never share a temporary), fsync'd, renamed
/// onto `path`, then the folder fsync'd. A kill or a power loss at any point leaves
/// the old file or the complete new one. Returns 0, or -1 with a message in err (the
/// temporary file is removed).
int fs_write_atomic(const char *path, const void *data, size_t size, char *err,
                    size_t err_size);

/// fsync `path` (a file or a folder) so that what was written to it, or renamed
/// into it, survives a power loss. Returns 0, or -1 with a message in err. A file
/// system that cannot sync a folder (EINVAL) counts as synced.
int fs_sync(const char *path, char *err, size_t err_size);

/// fsync the folder that holds `path` (its last '/' or "."), after a rename into it.
int fs_sync_parent(const char *path, char *err, size_t err_size);

/// Flush every file of the file system that holds `dir` (Linux syncfs): one call
/// instead of one fsync per file, for an OBJ sequence of thousands of frames. Falls
/// back to 1 (nothing done) where syncfs is missing; 0 done; -1 with err.
int fs_sync_filesystem(const char *dir, char *err, size_t err_size);

/// The size and the CRC-32 (zlib's) of a file's bytes. Returns 0, or -1 with err.
int fs_file_crc32(const char *path, uint64_t *size, uint32_t *crc, char *err, size_t err_size);

/// The lock file of an output folder, held by `rbcloth batch` for its whole run.
#define FS_LOCK_NAME ".rbcloth-batch.lock"

/// Outcomes of fs_lock_dir.
enum { FS_LOCK_TAKEN = 0, FS_LOCK_BUSY = 1, FS_LOCK_ERROR = -1 };

/// Lock the output folder `dir`: flock on DIR/.rbcloth-batch.lock (created when
/// `create`, opened O_CLOEXEC so that no exec'd helper keeps it), LOCK_EX when
/// `exclusive`, else LOCK_SH, never blocking on a live holder. With `owner`, the
/// file is rewritten with "PID HOST OWNER", which a refused process names.
///   FS_LOCK_TAKEN: *fd holds the lock until it is closed (or -1 when `create` is 0
///     and there is no lock file); err may hold a warning (a file system without
///     locks: the folder is not protected, but the run goes on).
///   FS_LOCK_BUSY: another process holds it; err says which (pid and host). A
///     holder whose pid is gone on this host (a killed batch whose workers, which
///     share the lock, are exiting) is waited for up to `wait_s` seconds first.
///   FS_LOCK_ERROR: err says why.
int fs_lock_dir(const char *dir, int exclusive, int create, const char *owner, double wait_s,
                int *fd, char *err, size_t err_size);

#endif
