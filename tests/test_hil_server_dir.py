"""The links directory of a served rack: held by one live server, written without
following symlinks, taken over cleanly from a dead server.

Servers run in this process (``HilServer``, the table only) except where a second
``station serve`` must be refused with its exit status and message.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import serial
from hil_helpers import serving

from laboratory import registry
from laboratory.connect import served_station
from station.config.isu import load_config
from station.hil import link_map, session
from station.hil.links_dir import LOCK, LinksDir, LinksDirError
from station.hil.server import HilServer

SECRET = "the victim's content\n"


def _server(links: Path) -> HilServer:
    return HilServer(served_station(registry.get("isu"), load_config()), 10.0, links,
                     only=["table"])


def _ask(url: str, cmd: bytes = b"*IDN?\n") -> bytes:
    with serial.serial_for_url(url, timeout=10.0) as port:
        port.write(cmd)
        return port.read_until(b"\n")


def test_fresh_directory_is_made_private_and_left_empty(tmp_path):
    links = tmp_path / "a" / "links"
    (tmp_path / "a").mkdir()
    with _server(links) as server:
        server.start()
        assert oct(links.stat().st_mode & 0o777) == "0o700"
        assert (links / LOCK).read_text().strip() == str(os.getpid())
        names = sorted(p.name for p in links.iterdir())
        assert names == sorted([LOCK, "links.json", "session.json", "table"])
        assert _ask(str(links / "table")).startswith(b"ISU-LAB,TT-4AX")
    assert list(links.iterdir()) == []


def test_second_server_is_refused_naming_the_first(tmp_path):
    links = tmp_path / "links"
    with _server(links) as first:
        first.start()
        before = (links / "links.json").read_text(), (links / "session.json").read_text()
        with pytest.raises(LinksDirError, match=rf"in use by a running server \(pid "
                                                 rf"{os.getpid()}\)"):
            _server(links)
        # the first is untouched and still reachable through what it published
        assert ((links / "links.json").read_text(), (links / "session.json").read_text()) \
            == before
        assert (links / LOCK).read_text().strip() == str(os.getpid())
        assert _ask(str(links / "table")).startswith(b"ISU-LAB,TT-4AX")


def test_second_serve_process_exits_2_and_leaves_the_first_reachable(tmp_path):
    with serving(tmp_path, ["--only", "table", "--speed", "10"]) as (links, entries, proc):
        before = (links / "links.json").read_text()
        second = subprocess.run(
            [sys.executable, "-m", "laboratory.cli", "serve", "--only", "table", "--links",
             str(links)], capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
        assert second.returncode == 2
        assert f"in use by a running server (pid {proc.pid})" in second.stderr
        assert second.stderr.count("\n") == 1  # one line, no traceback
        assert (links / "links.json").read_text() == before
        assert _ask(entries[0].address).startswith(b"ISU-LAB,TT-4AX")
    # the served process froze its heap and reports its garbage-collection pauses
    assert "garbage collections while serving: " in (tmp_path / "server.out").read_text()


def test_stale_directory_of_a_dead_server_is_taken_over(tmp_path):
    links = tmp_path / "links"
    links.mkdir(mode=0o700)
    (links / LOCK).write_text("999999\n")  # no process holds its lock
    (links / "links.json").write_text('[{"instrument": "table", "kind": "serial", '
                                      '"address": "/nowhere"}]')
    (links / "session.json").write_text("{}")
    (links / ".links.json.tmp").write_text("half a map")
    os.symlink("/dev/pts/9999", links / "counter1")  # a pty link of the dead server
    (links / "notes.txt").write_text("mine\n")  # not the server's: left alone
    with _server(links) as server:
        server.start()
        assert sorted(p.name for p in links.iterdir()) == sorted(
            [LOCK, "links.json", "session.json", "table", "notes.txt"])
        (entry,) = link_map.read(links)
        assert entry.address == str(links / "table")
        assert session.read(links).session == server.session_id
        assert (links / LOCK).read_text().strip() == str(os.getpid())
    assert [p.name for p in links.iterdir()] == ["notes.txt"]


def test_planted_symlinks_are_replaced_never_written_through(tmp_path):
    links = tmp_path / "links"
    links.mkdir(mode=0o700)
    victims = {}
    for name in (".links.json.tmp", ".session.json.tmp", "links.json", "session.json",
                 "table", ".table.tmp"):
        victim = tmp_path / f"victim-{name.strip('.')}"
        victim.write_text(SECRET)
        os.symlink(victim, links / name)
        victims[name] = victim
    with _server(links) as server:
        server.start()
        server.publish_session()  # re-written while serving, too
        assert not (links / "links.json").is_symlink()
        assert json.loads((links / "links.json").read_text())[0]["instrument"] == "table"
        assert os.readlink(links / "table").startswith("/dev/pts/")
    for victim in victims.values():
        assert victim.read_text() == SECRET
    assert list(links.iterdir()) == []


@pytest.mark.parametrize("plant", ["dir-symlink", "lock-symlink", "world-writable", "file"])
def test_unsafe_directories_are_refused(tmp_path, plant):
    links = tmp_path / "links"
    victim = tmp_path / "victim"
    victim.write_text(SECRET)
    if plant == "dir-symlink":
        real = tmp_path / "real"
        real.mkdir(mode=0o700)
        os.symlink(real, links)
        error, match = LinksDirError, "is a symlink or not a directory"
    elif plant == "lock-symlink":
        links.mkdir(mode=0o700)
        os.symlink(victim, links / LOCK)
        error, match = LinksDirError, r"\.lock is a symlink"
    elif plant == "world-writable":
        links.mkdir()
        links.chmod(0o777)
        error, match = LinksDirError, "writable by other users"
    else:  # a user's file where the table's symlink would go
        links.mkdir(mode=0o700)
        (links / "table").write_text(SECRET)
        error, match = FileExistsError, "exists and is not a symlink"
    with pytest.raises(error, match=match):
        _server(links)
    assert victim.read_text() == SECRET
    if plant == "file":
        assert (links / "table").read_text() == SECRET
        assert sorted(p.name for p in links.iterdir()) == ["table"]  # lock let go, removed


def test_links_dir_lets_go_and_is_taken_again(tmp_path):
    first = LinksDir(tmp_path / "d")
    with pytest.raises(LinksDirError):
        LinksDir(tmp_path / "d")
    first.write_text("links.json", "[]\n")
    first.close()
    second = LinksDir(tmp_path / "d")
    try:
        assert second.names() == [LOCK]  # the first's map was stale: removed
    finally:
        second.close()
    assert list((tmp_path / "d").iterdir()) == []
