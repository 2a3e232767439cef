"""One study at a time per output folder: a lock that a dead process does not hold.

``DIR/.twoscale-study.lock`` is locked with ``fcntl.lockf`` (a POSIX record lock, also
honoured over NFS) for as long as a run of ``twoscale study`` works in ``DIR``. The kernel
drops the lock when the process ends in any way, SIGKILL and a crash included, so a dead
run never blocks the next one; there is nothing to clean up by hand. The file also
records the holder's pid, host and start time, for the one line that refuses a second run
while the first is alive. The file itself stays (removing a lock file races with the next
locker).

Where the file system has no locks (``ENOLCK``), the run goes on with one warning: two
runs at once on that folder are then not detected.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import socket
import time
import warnings
from pathlib import Path
from typing import Iterator

from ..errors import StudyBusy

#: The lock file of a study folder.
LOCK_NAME = ".twoscale-study.lock"


def _holder(fd: int) -> str:
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode("utf-8") or "{}")
        since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(float(info["started"])))
        return f"pid {int(info['pid'])} on {info['host']}, since {since}"
    except (ValueError, KeyError, TypeError, OSError):
        return "holder unknown"


@contextlib.contextmanager
def study_lock(out: str | os.PathLike) -> Iterator[Path]:
    """Hold the lock of study folder ``out`` (created if needed) for the ``with`` block.

    Raises
    ------
    StudyBusy
        Another live process holds it (one line naming it).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            import fcntl

            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EACCES, errno.EAGAIN):
                raise StudyBusy(
                    f"--out {str(out)!r} is in use by another run of twoscale study "
                    f"({_holder(fd)}): wait for it to end or stop it (a run that died "
                    f"holds no lock), or choose another folder"
                ) from None
            if exc.errno != errno.ENOLCK:
                raise
            warnings.warn(
                f"{path}: the file system has no locks ({exc.strerror}): a second run on this "
                f"folder at the same time would not be detected",
                stacklevel=3,
            )
        record = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()})
        os.ftruncate(fd, 0)
        os.pwrite(fd, record.encode("utf-8"), 0)
        yield path
    finally:
        os.close(fd)  # releases the lock
