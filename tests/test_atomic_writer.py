"""The kernel's atomic writer (fortran/io/text_file.f90, write_text_file; issue 29, mutation
testing): a temporary file that the system kept shorter than what was written, with every
write call reporting success, is never renamed into place.

The fault is injected from outside pymr: an LD_PRELOAD shim (compiled here with gcc) wraps
libc's write() and pwrite() and, for a file whose name ends in a given suffix (the writer's
PATH.tmp), writes only the first half of what it is asked and reports all of it written. The
Fortran runtime then closes the file without an error, as on a disk that drops data; only the
size of the file on the disk tells. Expected, as for any failed run: exit status 2, one line
on stderr naming the file and the bytes (the shim's own count of what reached the file and of
what was asked), the earlier complete file byte for byte as it was, no PATH.tmp left.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

SHIM = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

/* write(), pwrite(), pwrite64() on a file whose path ends in $SHORT_WRITE_SUFFIX: only the
   first half of the bytes reaches the file, the call reports them all; each such call is
   logged to $SHORT_WRITE_LOG as "asked written path". */

static int short_target(int fd, char *path, size_t size)
{
    const char *suffix = getenv("SHORT_WRITE_SUFFIX");
    char link[64];
    ssize_t n;
    size_t ls;
    if (suffix == NULL || *suffix == '\0')
        return 0;
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    n = readlink(link, path, size - 1);
    if (n <= 0)
        return 0;
    path[n] = '\0';
    ls = strlen(suffix);
    return (size_t)n >= ls && strcmp(path + n - ls, suffix) == 0;
}

static void short_log(size_t asked, ssize_t written, const char *path)
{
    static ssize_t (*real_write)(int, const void *, size_t);
    const char *log = getenv("SHORT_WRITE_LOG");
    char line[4200];
    int fd, len;
    if (log == NULL)
        return;
    if (real_write == NULL)
        real_write = (ssize_t (*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    fd = open(log, O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd < 0)
        return;
    len = snprintf(line, sizeof line, "%zu %zd %s\n", asked, written, path);
    real_write(fd, line, (size_t)len);
    close(fd);
}

ssize_t write(int fd, const void *buf, size_t count)
{
    static ssize_t (*real)(int, const void *, size_t);
    char path[4096];
    ssize_t r;
    if (real == NULL)
        real = (ssize_t (*)(int, const void *, size_t))dlsym(RTLD_NEXT, "write");
    if (count == 0 || !short_target(fd, path, sizeof path))
        return real(fd, buf, count);
    r = real(fd, buf, count / 2);
    short_log(count, r, path);
    return r < 0 ? r : (ssize_t)count;
}

static ssize_t short_pwrite(const char *name, int fd, const void *buf, size_t count, off_t off)
{
    ssize_t (*real)(int, const void *, size_t, off_t);
    char path[4096];
    ssize_t r;
    real = (ssize_t (*)(int, const void *, size_t, off_t))dlsym(RTLD_NEXT, name);
    if (count == 0 || !short_target(fd, path, sizeof path))
        return real(fd, buf, count, off);
    r = real(fd, buf, count / 2, off);
    short_log(count, r, path);
    return r < 0 ? r : (ssize_t)count;
}

ssize_t pwrite(int fd, const void *buf, size_t count, off_t off)
{
    return short_pwrite("pwrite", fd, buf, count, off);
}

ssize_t pwrite64(int fd, const void *buf, size_t count, off_t off)
{
    return short_pwrite("pwrite64", fd, buf, count, off);
}
"""


@pytest.fixture(scope="module")
def shim(tmp_path_factory) -> Path:
    """The shim's shared library; the test fails (is not skipped) without gcc."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.fail("gcc not found: the fault-injection shim of these tests is compiled with gcc")
    folder = tmp_path_factory.mktemp("shim")
    (folder / "short_write.c").write_text(SHIM)
    lib = folder / "short_write.so"
    r = subprocess.run([gcc, "-shared", "-fPIC", "-O1", "-o", str(lib), str(folder / "short_write.c"), "-ldl"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return lib


def short_writes(cmd, cwd: Path, lib: Path, suffix: str):
    """Run `cmd` with the shim shortening the writes to files ending in `suffix`; returns the
    completed process and the shim's log lines (asked, written, path)."""
    log = cwd / "short_write.log"
    env = dict(os.environ, LD_PRELOAD=str(lib), SHORT_WRITE_SUFFIX=suffix, SHORT_WRITE_LOG=str(log))
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=120)
    entries = [(int(a), int(w), p) for a, w, p in (ln.split(" ", 2) for ln in log.read_text().splitlines())] \
        if log.exists() else []
    log.unlink(missing_ok=True)
    return r, entries


def check_refused(r, entries, folder: Path, name: str, before: bytes, prefix: str) -> None:
    """The failed write: the shim did shorten the temporary file; exit 2 with one line naming
    the file and the bytes on the disk against those asked; the earlier file as it was."""
    assert entries, f"the shim shortened no write to {name}.tmp (the runtime wrote it another way?); " \
                    f"exit {r.returncode}, stderr {r.stderr!r}"
    asked, written = sum(e[0] for e in entries), sum(e[1] for e in entries)
    assert all(p.endswith(name + ".tmp") for _, _, p in entries) and 0 <= written < asked
    now = (folder / name).read_bytes()
    assert r.returncode == 2, (f"exit {r.returncode} (2 expected), stderr {r.stderr!r}; {name} is now {len(now)} "
                               f"bytes (the earlier file {len(before)}; the shim let {written} of {asked} bytes "
                               "reach the temporary file)")
    assert r.stderr.count("\n") == 1 and r.stderr.startswith(prefix), r.stderr
    assert name in r.stderr and re.search(rf"\b{written}\b.*\b{asked}\b", r.stderr), r.stderr
    assert now == before, f"{name} changed: {len(now)} bytes, {len(before)} before"
    assert not list(folder.glob("*.tmp")), sorted(p.name for p in folder.iterdir())
    assert not list(folder.glob("*.lock")), sorted(p.name for p in folder.iterdir())


def test_modal_file_shortened_on_disk_is_not_renamed_over_the_earlier_one(tmp_path, shim):
    """`pymr modal-file` (the kernel's write_modal_file through write_text_file): the modes of
    beam link1 written, then those of link2 to the same file with the temporary file kept at
    half its size: refused, link1's file left whole. The same command without the shim
    replaces the file (the shim is what makes it fail)."""
    (tmp_path / "chain.nml").write_bytes((ROOT / "input" / "flexible_chain.nml").read_bytes())
    cmd = [sys.executable, "-m", "pymr", "modal-file", "chain.nml", "{body}", "-o", "out.modal", "--quiet"]
    first = subprocess.run([c.format(body="link1") for c in cmd], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
    assert first.returncode == 0, first.stderr
    before = (tmp_path / "out.modal").read_bytes()
    r, entries = short_writes([c.format(body="link2") for c in cmd], tmp_path, shim, "out.modal.tmp")
    check_refused(r, entries, tmp_path, "out.modal", before, "pymr: error: ")
    again, entries = short_writes([c.format(body="link2") for c in cmd], tmp_path, shim, "no-such-file.tmp")
    assert again.returncode == 0 and not entries, again.stderr
    assert (tmp_path / "out.modal").read_bytes() != before


def test_statistics_shortened_on_disk_are_not_renamed_over_the_earlier_ones(tmp_path, shim, mrsim):
    """mrsim's statistics (OUT.json, written through write_text_file at the end of a run):
    an earlier complete run's, then a longer run with OUT.json.tmp kept at half its size:
    the run fails (exit 2, one line naming out.json), the earlier statistics stay whole, and
    so do the earlier results they describe (the rows are put in place only once the
    statistics are complete; they stay in OUT.csv.partial)."""
    scene = (ROOT / "input" / "pendulum.nml").read_text().replace(
        "&output file = 'pendulum.csv', dt = 0.01 /", "&output dt = 0.01 /")
    (tmp_path / "p.nml").write_text(scene)
    cmd = [mrsim, "p.nml", "-o", "out.csv", "--quiet", "--set"]
    first = subprocess.run(cmd + ["scene.t_end=0.05"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    before = (tmp_path / "out.json").read_bytes()
    rows_before = (tmp_path / "out.csv").read_bytes()
    r, entries = short_writes(cmd + ["scene.t_end=0.1"], tmp_path, shim, "out.json.tmp")
    check_refused(r, entries, tmp_path, "out.json", before, "mrsim: error: ")
    assert (tmp_path / "out.csv").read_bytes() == rows_before, "the earlier results were replaced by a failed run"
    assert (tmp_path / "out.csv.partial").exists()
