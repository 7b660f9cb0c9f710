"""Windows and macOS: every branch of app/host.py that depends on the system runs here, with ``sys.platform``
(and ``os.name`` where the code reads it) set to Windows' and macOS' values and the calls those systems lack
removed from ``os``; and ``commission sim`` stops on Ctrl+C through the fallback a Windows event loop needs."""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import textwrap
import threading
import types
from pathlib import Path

import pytest
from conftest import free_port

from app import host, memory, realtime, runtime, web
from app.users import UserStore, default_data_dir
from plants import modbus_line, plant_text

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def windows(monkeypatch):
    """This process as Windows' Python would see it, as far as the code branches on it: ``sys.platform`` is
    "win32" and the POSIX-only calls are missing from ``os``. (``os.name`` stays: pathlib picks its classes by
    it and cannot make Windows paths here; :func:`test_os_name_nt_alone_means_windows` covers that branch.)"""
    import platformdirs.windows  # noqa: F401 - imported as on Linux before the platform changes

    monkeypatch.setattr(sys, "platform", "win32")
    for name in ("sched_setscheduler", "sched_getscheduler", "sched_getparam", "sched_param", "setpriority",
                 "getpriority", "getsid", "fchmod", "PRIO_PROCESS", "SCHED_RR", "SCHED_OTHER", "SCHED_RESET_ON_FORK"):
        monkeypatch.delattr(os, name, raising=False)
    return monkeypatch


@pytest.fixture
def macos(monkeypatch):
    """``sys.platform`` "darwin" and no Linux scheduling calls (macOS' Python has no sched_setscheduler)."""
    monkeypatch.setattr(sys, "platform", "darwin")
    for name in ("sched_setscheduler", "sched_getscheduler", "sched_getparam", "sched_param"):
        monkeypatch.delattr(os, name, raising=False)
    return monkeypatch


def _no_chmod(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError(f"chmod{args} on Windows: the profile's ACL protects the file, a mode means nothing")

    monkeypatch.setattr(os, "chmod", refuse)
    monkeypatch.setattr(Path, "chmod", refuse)
    monkeypatch.setattr(os, "umask", refuse)


def _no_proc(monkeypatch):
    import builtins

    real_open = builtins.open

    def guarded(file, *args, **kwargs):
        if str(file).startswith(("/proc", "/sys")):
            raise AssertionError(f"{file} read on a system that has no such file")
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", guarded)


# -- which system -------------------------------------------------------------------------------------------------

def test_os_name_nt_alone_means_windows(monkeypatch):
    monkeypatch.setattr(os, "name", "nt")
    assert host.is_windows()
    monkeypatch.setattr(os, "name", "posix")
    monkeypatch.setattr(sys, "platform", "darwin")
    assert host.is_macos() and not host.is_windows() and not host.is_linux()


# -- the data folder ----------------------------------------------------------------------------------------------

@pytest.fixture
def home(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    for name in ("COMMISSION_DATA_DIR", "XDG_DATA_HOME"):
        monkeypatch.delenv(name, raising=False)
    return tmp_path / "home"


def test_data_folder_on_linux_is_where_it_always_was(home, monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    assert host.data_dir() == home / ".local" / "share" / "commission" == default_data_dir()
    monkeypatch.setenv("XDG_DATA_HOME", str(home / "xdg"))
    assert host.data_dir() == home / "xdg" / "commission"


def test_data_folder_on_windows_is_local_appdata(home, windows):
    import platformdirs.windows

    local = "C:\\Users\\eng\\AppData\\Local"
    asked = []
    windows.setattr(platformdirs.windows, "get_win_folder", lambda name: asked.append(name) or local)
    assert host.data_dir() == Path(local) / "commission" == default_data_dir()
    assert set(asked) == {"CSIDL_LOCAL_APPDATA"}  # not the roaming folder: the audit log belongs to this machine


def test_data_folder_on_macos_is_application_support(home, macos):
    assert host.data_dir() == home / "Library" / "Application Support" / "commission" == default_data_dir()


def test_the_old_location_is_still_read_while_it_exists(home, macos):
    old = home / ".local" / "share" / "commission"
    old.mkdir(parents=True)
    (old / "users.toml").write_text("")
    assert host.data_dir() == old  # an installation that ran an earlier version keeps its accounts and audit log
    new = home / "Library" / "Application Support" / "commission"
    new.mkdir(parents=True)
    assert host.data_dir() == new  # once the platform's folder is there, it is the one


def test_commission_data_dir_wins_everywhere(home, tmp_path, monkeypatch):
    monkeypatch.setenv("COMMISSION_DATA_DIR", str(tmp_path / "mine"))
    for platform in ("linux", "win32", "darwin"):
        monkeypatch.setattr(sys, "platform", platform)
        assert host.data_dir() == tmp_path / "mine"


# -- files only their owner may read ------------------------------------------------------------------------------

def test_posix_protects_with_owner_only_modes(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    folder = tmp_path / "data"
    host.protect_folder(folder)
    assert web.storage_secret(folder)
    secret = folder / "session-secret"
    assert folder.stat().st_mode & 0o777 == 0o700 and secret.stat().st_mode & 0o777 == 0o600
    assert "0700" in host.protection()


def test_posix_umask_is_owner_only(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    masks = []
    monkeypatch.setattr(os, "umask", lambda mask: masks.append(mask) or 0o022)
    host.private_umask()
    assert masks == [0o077]


def test_windows_leaves_protection_to_the_profile_acl(tmp_path, windows):
    _no_chmod(windows)
    folder = tmp_path / "data"
    host.protect_folder(folder)
    host.private_umask()
    assert folder.is_dir()
    assert web.storage_secret(folder)  # the session secret: written, no mode set
    store = UserStore(folder / "users.toml")
    store.add("anna", "engineer", "long enough")  # the accounts file: written atomically, no mode set
    assert UserStore(folder / "users.toml").users["anna"].role == "engineer"
    assert "access control list" in host.protection()


def test_an_atomic_save_without_fchmod_keeps_the_folders_protection(tmp_path, windows):
    from app import files

    target = tmp_path / "site.toml"
    target.write_text("old")
    files.replace_atomic(target, "new")  # Windows before Python 3.13 has no os.fchmod
    assert target.read_text() == "new"


# -- scheduling -------------------------------------------------------------------------------------------------

def _in_thread(fn):
    out = {}
    thread = threading.Thread(target=lambda: out.update(result=fn(threading.get_native_id())))
    thread.start()
    thread.join()
    return out["result"]


class FakeKernel32:
    """Windows' kernel32 as far as app/host.py calls it; ``refuse``: every call fails as Windows' do (0)."""

    def __init__(self, refuse: bool = False):
        self.refuse, self.calls = refuse, []

    def OpenThread(self, access, inherit, tid):
        self.calls.append(("OpenThread", access, inherit, tid))
        return 0 if self.refuse else 0x1234

    def SetThreadPriority(self, handle, priority):
        self.calls.append(("SetThreadPriority", handle, priority))
        return 1

    def CloseHandle(self, handle):
        self.calls.append(("CloseHandle", handle))
        return 1

    def GetCurrentProcess(self):
        return -1

    def SetPriorityClass(self, handle, cls):
        self.calls.append(("SetPriorityClass", handle, cls))
        return 0 if self.refuse else 1


def test_windows_keepalive_thread_runs_time_critical(windows):
    _no_proc(windows)
    kernel32 = FakeKernel32()
    windows.setattr(host, "_kernel32", lambda: kernel32)
    tid = {}
    assert _in_thread(lambda t: tid.update(t=t) or realtime.raise_sender(t, 0.1)) == "time-critical"
    assert kernel32.calls == [("OpenThread", host.THREAD_SET_INFORMATION, False, tid["t"]),
                              ("SetThreadPriority", 0x1234, host.THREAD_PRIORITY_TIME_CRITICAL), ("CloseHandle", 0x1234)]
    assert host.real_time_bounded() is False
    realtime.hold_keepalive()  # the other threads: nothing to raise, nothing raised
    try:
        assert realtime.holders_raised() == []
    finally:
        realtime.release_keepalive()
    kernel32.calls.clear()
    assert runtime.raise_priority() is True  # no nice values: the above-normal priority class instead
    assert kernel32.calls == [("SetPriorityClass", -1, host.ABOVE_NORMAL_PRIORITY_CLASS)]


def test_windows_refusing_a_priority_leaves_the_thread_as_it_is(windows):
    windows.setattr(host, "_kernel32", lambda: FakeKernel32(refuse=True))
    assert _in_thread(lambda tid: realtime.raise_sender(tid, 0.1)) == "as it is"
    assert runtime.raise_priority() is False


def test_windows_priorities_are_not_tried_elsewhere(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    monkeypatch.setattr(host, "_kernel32", lambda: pytest.fail("kernel32 off Windows"))
    with pytest.raises(host.Unsupported):
        host.set_thread_time_critical(1)
    with pytest.raises(host.Unsupported):
        host.set_process_above_normal()


def test_macos_never_gives_a_thread_id_to_setpriority(macos):
    _no_proc(macos)
    calls = []
    macos.setattr(os, "setpriority", lambda *args: calls.append(args))
    assert _in_thread(lambda tid: realtime.raise_sender(tid, 0.1)) == "as it is"
    assert calls == []  # a macOS thread id is no process id: it must not reach setpriority
    assert host.real_time_bounded() is False
    macos.setattr(os, "getpriority", lambda *args: 0)
    runtime.raise_priority()  # the process itself: setpriority(PRIO_PROCESS, 0, -5) where permitted
    assert calls == [(os.PRIO_PROCESS, 0, runtime.PROCESS_NICE)]


def test_linux_reads_the_kernels_throttling(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    if not Path("/proc/sys/kernel/sched_rt_runtime_us").exists():
        pytest.skip("no /proc here")
    expected = (os.cpu_count() or 1) >= 2 and 0 <= int(Path("/proc/sys/kernel/sched_rt_runtime_us").read_text()) \
        < int(Path("/proc/sys/kernel/sched_rt_period_us").read_text())
    assert host.real_time_bounded() is expected


# -- the C allocator and the kernel's counters ----------------------------------------------------------------

@pytest.mark.parametrize("platform", ["win32", "darwin"])
def test_no_heap_trim_and_no_drop_counters_off_linux(platform, monkeypatch):
    import socket

    monkeypatch.setattr(sys, "platform", platform)
    _no_proc(monkeypatch)
    assert host.heap_trimmer() is None
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        assert host.socket_drops(sock) is None
    assert host.udp_drops(1) is None and host.netdev_drops("can0") is None
    monkeypatch.setattr(memory, "_malloc_trim", None)
    assert memory.trim() is False
    asyncio.run(asyncio.wait_for(memory.keep_trimmed(0.01), 2))  # returns at once: nothing to trim


def test_linux_drop_counter_of_a_udp_socket():
    import socket

    if not sys.platform.startswith("linux"):
        pytest.skip("Linux only")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        drops = host.socket_drops(sock)
        if drops is None:  # a kernel before 4.7
            drops = host.udp_drops(os.fstat(sock.fileno()).st_ino)
        assert drops == 0
    if Path("/sys/class/net/lo/statistics/rx_dropped").exists():
        assert isinstance(host.netdev_drops("lo"), int)  # the figures a SocketCAN interface has too


# -- stopping on Ctrl+C -------------------------------------------------------------------------------------------

def test_windows_stops_on_ctrl_break_too(windows):
    windows.setattr(signal, "SIGBREAK", 21, raising=False)
    assert host.stop_signals() == (signal.SIGINT, signal.SIGTERM, 21)


def test_unix_stop_signals_are_the_loops(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    assert host.stop_signals() == (signal.SIGINT, signal.SIGTERM)

    async def main():
        loop = asyncio.get_running_loop()
        stop = asyncio.Event()
        before = signal.getsignal(signal.SIGINT)
        undo = host.on_stop_signals(loop, stop.set)
        try:
            signal.raise_signal(signal.SIGINT)
            await asyncio.wait_for(stop.wait(), 5)
        finally:
            undo()
        assert signal.getsignal(signal.SIGINT) == before  # the loop's handler is gone, the one before is back

    asyncio.run(main())


def test_a_loop_without_signal_handlers_stops_through_the_interpreters_handler():
    """Windows' event loops raise NotImplementedError from add_signal_handler: signal.signal takes over."""

    async def main():
        loop = asyncio.get_running_loop()

        def refuse(*_args):
            raise NotImplementedError

        loop.add_signal_handler = refuse  # this loop as Windows' loops are
        stop = asyncio.Event()
        before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
        undo = host.on_stop_signals(loop, stop.set)
        try:
            assert signal.getsignal(signal.SIGINT) not in before
            signal.raise_signal(signal.SIGINT)
            await asyncio.wait_for(stop.wait(), 5)
            stop.clear()
            signal.raise_signal(signal.SIGTERM)
            await asyncio.wait_for(stop.wait(), 5)
        finally:
            undo()
        assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before

    asyncio.run(main())


WINDOWS_LOOP = textwrap.dedent("""
    import asyncio, sys

    class WindowsLikeLoop(asyncio.SelectorEventLoop):
        def add_signal_handler(self, sig, callback, *args):
            print(f"add_signal_handler({int(sig)}): NotImplementedError", file=sys.stderr, flush=True)
            raise NotImplementedError  # what Windows' event loops do

    class Policy(asyncio.DefaultEventLoopPolicy):
        def new_event_loop(self):
            return WindowsLikeLoop()

    asyncio.set_event_loop_policy(Policy())
    from app.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_commission_sim_stops_on_ctrl_c_where_the_loop_has_no_signal_handlers(tmp_path):
    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(modbus_line(port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, poll_period=0.1,
                                            retries=None), name=None))
    env = dict(os.environ, PYTHONPATH=str(ROOT), COMMISSION_DATA_DIR=str(tmp_path / "data"))
    proc = subprocess.Popen([sys.executable, "-c", WINDOWS_LOOP, "sim", "--plant", str(plant)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert "simulating" in line, line + proc.stderr.read() if proc.poll() is not None else line
        watchdog = threading.Timer(30, proc.kill)  # a hung read below ends with the process
        watchdog.start()
        refused = []
        try:
            while f"add_signal_handler({int(signal.SIGTERM)})" not in "".join(refused):  # both asked (SIGINT first)
                line = proc.stderr.readline()
                assert line, "".join(refused)
                refused.append(line)
        finally:
            watchdog.cancel()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)
        err = "".join(refused) + proc.stderr.read()
        assert code == 0, err
        assert "Traceback" not in err and "NotImplementedError" in err, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


# -- single keys at a terminal ----------------------------------------------------------------------------------

async def _two_keys(keys, typed=lambda: None) -> list[str]:
    """What ``keys`` hands on once started and ``typed()`` ran, until two keys came (5 s at the most); stopped after."""
    got: list[str] = []
    keys.start(got.append)
    try:
        typed()
        loop = asyncio.get_running_loop()
        end = loop.time() + 5
        while len(got) < 2 and loop.time() < end:
            await asyncio.sleep(0.01)
    finally:
        keys.stop()
    return got


def test_windows_terminal_keys_come_from_msvcrt(windows):
    """A checkout's yes/no at a Windows console: msvcrt's key buffer, arrow keys (two codes) skipped."""
    pending = list(" \xe0Hn")
    lock = threading.Lock()

    def kbhit():
        with lock:
            return bool(pending)

    def getwch():
        with lock:
            return pending.pop(0)

    windows.setitem(sys.modules, "msvcrt", types.SimpleNamespace(kbhit=kbhit, getwch=getwch))

    from app.headless import TtyKeys

    keys = TtyKeys(stream=types.SimpleNamespace(fileno=lambda: (_ for _ in ()).throw(AssertionError("no termios"))))
    assert asyncio.run(_two_keys(keys)) == [" ", "n"]


def test_posix_terminal_keys_use_cbreak_mode_and_restore_it(monkeypatch):
    """The same class on a POSIX terminal: a pseudo-terminal in cbreak mode while it reads, as it was after."""
    import pty
    import termios

    monkeypatch.setattr(sys, "platform", "linux")
    leader, follower = pty.openpty()
    stream = os.fdopen(follower, "r", closefd=False)
    before = termios.tcgetattr(follower)
    try:
        def typed() -> None:
            assert not termios.tcgetattr(follower)[3] & termios.ICANON  # cbreak: no line editing
            os.write(leader, b" n")

        assert asyncio.run(_two_keys(host.TerminalKeys(stream), typed)) == [" ", "n"]
        assert termios.tcgetattr(follower) == before
    finally:
        os.close(leader)
        os.close(follower)
