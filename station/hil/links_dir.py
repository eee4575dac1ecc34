"""The directory a rack server publishes its links in, written without following symlinks
and held by one live server at a time.

Everything is done relative to an open descriptor of the directory, never through a path
a second time: files are written to a fresh name made with ``O_CREAT | O_EXCL |
O_NOFOLLOW`` and renamed over their final name, symlinks are made under a fresh name and
renamed likewise, so a symlink planted in the directory (``.links.json.tmp -> victim``,
``links.json -> victim``) is replaced, never written through. The directory itself must
not be a symlink, must belong to the server's user and must not be writable by others.

:class:`LinksDir` adds the hold: an ``fcntl.flock`` on ``DIR/.lock``, which holds the pid
of the server. A second server on the same directory is refused, naming that pid, before
it touches anything; a directory left by a dead server (the kernel released its lock) is
taken over: its map, session, temporary files and pty symlinks are removed first.
"""

from __future__ import annotations

import errno
import fcntl
import os
import secrets
import stat
from pathlib import Path

LOCK = ".lock"
TMP_SUFFIX = ".tmp"
PTY_PREFIX = "/dev/pts/"
PUBLISHED = ("links.json", "session.json")  # link_map.FILENAME, session.FILENAME
_NOFOLLOW = os.O_NOFOLLOW | os.O_CLOEXEC


class LinksDirError(ValueError):
    """The links directory cannot be used (held by a live server, a symlink, not ours)."""


class DirHandle:
    """An open directory: write files and symlinks in it without following symlinks."""

    def __init__(self, path: Path, create: bool = False) -> None:
        path = Path(path)
        self.path = path.parent.resolve() / path.name  # the last component is not followed
        parent = os.open(self.path.parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            if create:
                try:
                    os.mkdir(path.name, 0o700, dir_fd=parent)
                except FileExistsError:
                    pass
            try:
                self.fd = os.open(path.name, os.O_RDONLY | os.O_DIRECTORY | _NOFOLLOW,
                                  dir_fd=parent)
            except OSError as e:
                if e.errno in (errno.ELOOP, errno.ENOTDIR):
                    raise LinksDirError(f"links directory {self.path} is a symlink or not a "
                                        f"directory: refusing to use it") from None
                raise
        finally:
            os.close(parent)

    def __truediv__(self, name: str) -> Path:
        return self.path / name

    def _fresh(self, name: str) -> str:
        return f".{name}.{secrets.token_hex(6)}{TMP_SUFFIX}"

    def write_bytes(self, name: str, data: bytes, mode: int = 0o644) -> Path:
        """Write ``name`` atomically: a fresh file (never an existing one), then rename."""
        while True:
            tmp = self._fresh(name)
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, mode,
                             dir_fd=self.fd)
            except FileExistsError:
                continue
            break
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, name, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        except BaseException:
            self.unlink(tmp)
            raise
        return self / name

    def write_text(self, name: str, text: str) -> Path:
        return self.write_bytes(name, text.encode())

    def symlink(self, name: str, target: str) -> Path:
        """Point symlink ``name`` at ``target`` atomically; refuse to replace anything that
        is not a symlink (a user's file of that name)."""
        try:
            st = os.stat(name, dir_fd=self.fd, follow_symlinks=False)
        except FileNotFoundError:
            pass
        else:
            if not stat.S_ISLNK(st.st_mode):
                raise FileExistsError(f"{self / name} exists and is not a symlink: "
                                      f"not replacing it")
        while True:
            tmp = self._fresh(name)
            try:
                os.symlink(target, tmp, dir_fd=self.fd)
            except FileExistsError:
                continue
            break
        try:
            os.replace(tmp, name, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        except BaseException:
            self.unlink(tmp)
            raise
        return self / name

    def readlink(self, name: str) -> str | None:
        try:
            return os.readlink(name, dir_fd=self.fd)
        except OSError:
            return None

    def unlink(self, name: str, if_target: str | None = None) -> None:
        """Remove ``name`` (a file or symlink; only if it points at ``if_target`` if given)."""
        if if_target is not None and self.readlink(name) != if_target:
            return
        try:
            os.unlink(name, dir_fd=self.fd)
        except FileNotFoundError:
            pass

    def names(self) -> list[str]:
        return os.listdir(self.fd)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def _holder_pid(fd: int) -> str:
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    except OSError:
        return "unknown"
    return text if text.isdigit() else "unknown"


class LinksDir(DirHandle):
    """The links directory of one live server (see the module doc); ``close`` lets go."""

    def __init__(self, path: Path) -> None:
        super().__init__(path, create=True)
        self._lock = -1
        try:
            self._check_owner()
            self._lock = self._hold()
            self.clear_stale()
        except BaseException:
            self.close()
            raise

    def _check_owner(self) -> None:
        st = os.fstat(self.fd)
        if st.st_uid != os.geteuid():
            raise LinksDirError(f"links directory {self.path} belongs to another user "
                                f"(uid {st.st_uid}): use a directory of your own")
        if st.st_mode & stat.S_IWOTH:
            raise LinksDirError(f"links directory {self.path} is writable by other users "
                                f"(mode {stat.S_IMODE(st.st_mode):o}): use a directory of "
                                f"your own")

    def _hold(self) -> int:
        """Lock ``DIR/.lock`` (the file the directory names now) and write our pid in it."""
        while True:
            try:
                fd = os.open(LOCK, os.O_RDWR | os.O_CREAT | _NOFOLLOW, 0o644, dir_fd=self.fd)
            except OSError as e:
                if e.errno == errno.ELOOP:
                    raise LinksDirError(f"{self / LOCK} is a symlink: refusing to use "
                                        f"{self.path}") from None
                raise
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _holder_pid(fd)
                os.close(fd)
                raise LinksDirError(f"links directory {self.path} is in use by a running "
                                    f"server (pid {pid}): stop it or use another "
                                    f"--links directory") from None
            mine = os.fstat(fd)
            try:
                now = os.stat(LOCK, dir_fd=self.fd, follow_symlinks=False)
            except FileNotFoundError:
                now = None
            if now is not None and (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
                break
            os.close(fd)  # a server that was letting go removed it meanwhile: again
        if not stat.S_ISREG(mine.st_mode):
            os.close(fd)
            raise LinksDirError(f"{self / LOCK} is not a regular file: refusing to use "
                                f"{self.path}")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        return fd

    def clear_stale(self) -> None:
        """Remove what a dead server published: map, session, temporary files, pty links."""
        for name in self.names():
            if name == LOCK:
                continue
            try:
                st = os.stat(name, dir_fd=self.fd, follow_symlinks=False)
            except FileNotFoundError:
                continue
            is_link = stat.S_ISLNK(st.st_mode)
            stale = name in PUBLISHED or (name.startswith(".") and name.endswith(TMP_SUFFIX))
            if is_link and (self.readlink(name) or "").startswith(PTY_PREFIX):
                stale = True
            if stale and (is_link or stat.S_ISREG(st.st_mode)):
                self.unlink(name)

    def close(self) -> None:
        """Let go of the directory: remove the lock file (while still holding it)."""
        if self._lock >= 0:
            if self.fd >= 0:
                mine = os.fstat(self._lock)
                try:
                    now = os.stat(LOCK, dir_fd=self.fd, follow_symlinks=False)
                    if (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
                        os.unlink(LOCK, dir_fd=self.fd)
                except FileNotFoundError:
                    pass
            os.close(self._lock)
            self._lock = -1
        super().close()


def write_text(links_dir: DirHandle | Path, name: str, text: str) -> Path:
    """Write ``name`` in a links directory atomically, following no symlink, through an
    open handle or by opening the directory for this one write."""
    if isinstance(links_dir, DirHandle):
        return links_dir.write_text(name, text)
    d = DirHandle(Path(links_dir))
    try:
        return d.write_text(name, text)
    finally:
        d.close()
