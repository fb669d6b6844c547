/* How the view opens a file of the run folder (docs/view.md, "Safety"): only a regular file that
 * sits in the folder itself. A symbolic link is never followed (it could name /etc/passwd or a
 * file of another run), and a FIFO or device is never read (a FIFO named live.json would block a
 * server thread for ever): the name is checked with lstat, opened with O_NOFOLLOW | O_NONBLOCK
 * and the open file checked again with fstat, so a file swapped between the two checks is still
 * caught. Refusals name the file and why, never anything read from it. */
#include "view/view_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *kind_of(mode_t mode) {
    return S_ISLNK(mode)                    ? "a symbolic link"
           : S_ISFIFO(mode)                 ? "a FIFO"
           : S_ISDIR(mode)                  ? "a folder"
           : S_ISSOCK(mode)                 ? "a socket"
           : S_ISCHR(mode) || S_ISBLK(mode) ? "a device"
                                            : "not a regular file";
}

static int refuse(const char *name, mode_t mode, rths_error *err) {
    rths_error_set(err, RTHS_EINPUT,
                   "refused: %s in the run folder is %s; the view reads only regular files of "
                   "the folder itself",
                   name, kind_of(mode));
    return 403;
}

int view_file_open(const char *dir, const char *name, view_file *f, rths_error *err) {
    memset(f, 0, sizeof *f);
    f->fd = -1;
    char *path = rths_path_join(dir, name);
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory"), 500;
    struct stat named;
    int status = 200;
    if (lstat(path, &named) != 0) {
        status = errno == ENOENT || errno == ENOTDIR ? 404 : 500;
        rths_error_set(err, status == 404 ? RTHS_EINPUT : RTHS_EFAIL, "%s: %s", name,
                       strerror(errno));
    } else if (!S_ISREG(named.st_mode)) {
        status = refuse(name, named.st_mode, err); /* never opened: no FIFO or device touched */
    } else if ((f->fd = open(path, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_NOCTTY | O_CLOEXEC)) <
               0) {
        int e = errno;
        status = e == ELOOP ? refuse(name, S_IFLNK, err) : e == ENOENT ? 404 : 500;
        if (e != ELOOP)
            rths_error_set(err, status == 404 ? RTHS_EINPUT : RTHS_EFAIL, "%s: %s", name,
                           strerror(e));
    } else if (fstat(f->fd, &f->st) != 0) {
        status = 500;
        rths_error_set(err, RTHS_EFAIL, "%s: %s", name, strerror(errno));
    } else if (!S_ISREG(f->st.st_mode)) {
        status = refuse(name, f->st.st_mode, err); /* replaced after the lstat */
    }
    free(path);
    if (status != 200) {
        view_file_close(f);
        return status;
    }
    snprintf(f->proc_path, sizeof f->proc_path, "/proc/self/fd/%d", f->fd);
    return 200;
}

void view_file_close(view_file *f) {
    if (f->fd >= 0) close(f->fd);
    f->fd = -1;
}

int view_file_present(const char *dir, const char *name) {
    char *path = rths_path_join(dir, name);
    struct stat st;
    int present = path && lstat(path, &st) == 0;
    free(path);
    return present;
}

int view_file_parse_check(const view_file *f, const char *name, rths_error *err) {
    if ((unsigned long long)f->st.st_size <= VIEW_MAX_PARSED_BYTES) return 200;
    rths_error_set(err, RTHS_EFAIL,
                   "%s is %lld bytes, more than the view reads into memory (%d MiB); read the "
                   "file itself",
                   name, (long long)f->st.st_size, (int)(VIEW_MAX_PARSED_BYTES >> 20));
    return 500;
}

void view_error_rename(rths_error *err, const char *from, const char *to) {
    char out[sizeof err->msg];
    size_t n = 0, from_len = strlen(from), to_len = strlen(to);
    for (const char *p = err->msg; *p && n + 1 < sizeof out;) {
        if (!strncmp(p, from, from_len) && n + to_len + 1 < sizeof out) {
            memcpy(out + n, to, to_len);
            n += to_len;
            p += from_len;
        } else {
            out[n++] = *p++;
        }
    }
    out[n] = 0;
    memcpy(err->msg, out, n + 1);
}
