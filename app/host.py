"""What differs between the systems the tool runs on: Linux, Windows and macOS.

Every call that only some systems have is made here and nowhere else (tests/app/test_platform_layering.py
parses app/, devices/, pages/ and server/ and fails on one outside this module), each with the fallback
the other systems get. What each system gets (docs/windows-macos.md says it for users):

- the data folder (:func:`data_dir`): platformdirs' user data folder, ``~/.local/share/commission`` on
  Linux, ``%LOCALAPPDATA%\\commission`` on Windows, ``~/Library/Application Support/commission`` on macOS;
  the old ``~/.local/share/commission`` is still used while it exists and the new one does not;
- owner-only files (:func:`protect_folder`, :func:`protect_file`, :func:`private_umask`): modes 0700/0600
  and umask 077 on POSIX; on Windows the user profile's ACL, no modes;
- stopping on Ctrl+C (:func:`on_stop_signals`): the event loop's signal handlers on Unix; on Windows, whose
  loops have none, ``signal.signal`` handing the stop to the loop, Ctrl+Break too;
- keep-alive sender threads (:func:`set_thread_round_robin`, :func:`set_nice`,
  :func:`set_thread_time_critical`): real-time round robin or a better nice value on Linux, the
  time-critical thread priority on Windows, as they are on macOS;
- the process's priority (:func:`set_nice`, :func:`raise_session_group`, :func:`set_process_above_normal`):
  nice -5 and its session group (``/proc/self/autogroup``) on Linux, nice -5 where permitted on macOS,
  the above-normal priority class on Windows;
- heap pages given back (:func:`heap_trimmer`): glibc's ``malloc_trim`` on Linux, nothing elsewhere;
- the kernel's drop counters (:func:`socket_drops`, :func:`udp_drops`, :func:`netdev_drops`): ``SO_MEMINFO``,
  ``/proc`` and ``/sys`` on Linux, None elsewhere;
- single keys at a terminal (:class:`TerminalKeys`): termios cbreak mode and select on POSIX, ``msvcrt``
  on Windows;
- an atomic save's file mode (:func:`copy_mode`): ``fchmod`` where the system has it.

The branches read ``sys.platform`` and ``os.name`` when called, not at import, so tests set them to Windows'
and macOS' values and run those branches here (tests/app/test_platform.py). Where a call may simply be missing
or refused the module tries it and falls back (:class:`Unsupported` is an OSError, so callers that already
catch OSError need nothing new).
"""

from __future__ import annotations

import errno
import os
import signal
import struct
import sys
from collections.abc import Callable
from pathlib import Path

from devices.errors import CommissionError

APP_NAME = "commission"


def is_windows() -> bool:
    return os.name == "nt" or sys.platform == "win32"


def is_macos() -> bool:
    return sys.platform == "darwin"


def is_linux() -> bool:
    return sys.platform.startswith("linux")


class Unsupported(CommissionError, OSError):
    """This system has no such call (Windows, macOS): the caller's documented fallback applies."""


def _os_call(name: str):
    """``os.<name>``, looked up now (tests replace it), or :class:`Unsupported` where the system has none."""
    function = getattr(os, name, None)
    if function is None:
        raise Unsupported(errno.ENOSYS, f"os.{name} is not available on {sys.platform}")
    return function


# -- the data folder -----------------------------------------------------------------------------------------

def legacy_data_dir() -> Path:
    """Where versions before the platform's own folder kept the data on every system:
    ``$XDG_DATA_HOME/commission``, else ``~/.local/share/commission``."""
    xdg = os.environ.get("XDG_DATA_HOME")
    return (Path(xdg) if xdg else Path.home() / ".local" / "share") / APP_NAME


def platform_data_dir() -> Path:
    """The user's data folder as the platform names it (platformdirs' ``user_data_dir("commission")``):
    Windows ``%LOCALAPPDATA%\\commission`` (not roaming: the audit log and backups belong to this machine),
    macOS ``~/Library/Application Support/commission``, Linux and other Unix ``$XDG_DATA_HOME/commission``
    or ``~/.local/share/commission``. The platform is the one ``sys.platform`` says now."""
    if is_windows():
        from platformdirs.windows import Windows as Dirs
    elif is_macos():
        from platformdirs.macos import MacOS as Dirs
    else:
        from platformdirs.unix import Unix as Dirs
    return Path(Dirs(APP_NAME, appauthor=False, roaming=False).user_data_dir)


def data_dir() -> Path:
    """Where accounts, the audit log, the record and backups live unless ``--data-dir`` says otherwise.

    ``COMMISSION_DATA_DIR`` wins; else the old location (:func:`legacy_data_dir`) while it exists and the
    platform's folder does not (a Windows or macOS installation that ran an earlier version keeps its
    accounts and audit log); else the platform's folder (:func:`platform_data_dir`). On Linux both are the
    same folder."""
    base = os.environ.get("COMMISSION_DATA_DIR")
    if base:
        return Path(base)
    new = platform_data_dir()
    old = legacy_data_dir()
    if old != new and old.is_dir() and not new.exists():
        return old
    return new


# -- files only their owner may read ---------------------------------------------------------------------------

PROTECTION = {
    "posix": "owner-only modes: folder 0700, files 0600",
    "nt": "the access control list of the user's profile folder (only the user and administrators): no modes are set",
}


def protection() -> str:
    """How the data folder's files are kept from other users of the machine, in words."""
    return PROTECTION["nt" if is_windows() else "posix"]


def protect_folder(path: str | Path) -> None:
    """Create ``path`` (with its parents) for the owner only. POSIX: mode 0700, also on a folder that was
    there; Windows: created under the user's profile, whose ACL already keeps other users out (a mode would
    only set the read-only attribute, which says nothing about who may read)."""
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True, mode=0o700)
    if not is_windows():
        os.chmod(path, 0o700)


def protect_file(path: str | Path) -> None:
    """``path`` readable and writable by its owner only: POSIX mode 0600; Windows: as its folder's ACL says
    (see :func:`protect_folder`), nothing is changed."""
    if not is_windows():
        os.chmod(path, 0o600)


def protect_database_sidecars(path: str | Path) -> None:
    """SQLite's write-ahead log and shared memory beside the database ``path`` (``-wal``, ``-shm``), where they
    exist, as :func:`protect_file` does the database."""
    for suffix in ("-wal", "-shm"):
        side = Path(path).with_name(Path(path).name + suffix)
        if side.exists():
            protect_file(side)


def private_umask() -> None:
    """Files this process creates from now on are its owner's only (POSIX umask 077); Windows has no umask
    that means this (the data folder's ACL does it)."""
    if not is_windows():
        os.umask(0o077)


def copy_mode(fd: int, mode: int) -> None:
    """Give the open file ``fd`` the permission bits ``mode`` (an atomic save keeps the file's mode). Where
    the system has no ``fchmod`` (Windows before Python 3.13) the new file keeps the folder's ACL."""
    try:
        _os_call("fchmod")(fd, mode)
    except Unsupported:
        pass


# -- stopping on Ctrl+C -------------------------------------------------------------------------------------------

def stop_signals() -> tuple[signal.Signals, ...]:
    """The signals that ask a command to stop: Ctrl+C and a termination request everywhere; on Windows
    Ctrl+Break too (the console's other interrupt key)."""
    signals = [signal.SIGINT, signal.SIGTERM]
    if is_windows() and hasattr(signal, "SIGBREAK"):
        signals.append(signal.SIGBREAK)
    return tuple(signals)


def on_stop_signals(loop, callback: Callable[[], None]) -> Callable[[], None]:
    """Call ``callback`` in ``loop`` when one of :func:`stop_signals` arrives; returns what undoes it.

    Where the loop handles signals itself (Unix: ``loop.add_signal_handler``) it does so. Windows' event
    loops raise NotImplementedError there: then the handler is the interpreter's (``signal.signal``, in the
    main thread), which hands the callback to the loop with ``call_soon_threadsafe`` (that wakes a loop that
    waits for I/O). Must be called from the main thread."""
    on_loop: list[int] = []
    previous: dict[int, object] = {}  # the handler each signal had: back in place at undo

    def handler(_signum, _frame) -> None:
        loop.call_soon_threadsafe(callback)

    for sig in stop_signals():
        previous[sig] = signal.getsignal(sig)
        try:
            loop.add_signal_handler(sig, callback)
            on_loop.append(sig)
            continue
        except NotImplementedError:  # Windows' loops: no signal handling of their own
            pass
        signal.signal(sig, handler)

    def undo() -> None:
        for sig in on_loop:
            loop.remove_signal_handler(sig)
        for sig, old in previous.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)

    return undo


def set_interrupt_handler(handler) -> object:
    """The interpreter's handler of Ctrl+C (SIGINT; every system has it); returns the one it replaces."""
    return signal.signal(signal.SIGINT, handler)


# -- scheduling: the keep-alive threads and the process ----------------------------------------------------------

def _reset_on_fork() -> int:
    return getattr(os, "SCHED_RESET_ON_FORK", 0)


def ordinary_policy() -> int:
    return getattr(os, "SCHED_OTHER", 0)


def round_robin_policy() -> int:
    return getattr(os, "SCHED_RR", 2)


def set_thread_round_robin(native_id: int, priority: int, reset_on_fork: bool = False) -> None:
    """Thread ``native_id`` under the round-robin real-time policy at ``priority`` (Linux, CAP_SYS_NICE).
    Raises OSError where it is not permitted, :class:`Unsupported` where the system has no such policy
    (Windows, macOS): the caller falls back to a nice value or leaves the thread as it is."""
    policy = _os_call("sched_setscheduler")
    param = _os_call("sched_param")
    policy(native_id, round_robin_policy() | (_reset_on_fork() if reset_on_fork else 0), param(priority))


def policy_kind(policy: int) -> int:
    """A policy as :func:`thread_policy_raw` reports it, without the reset-on-fork flag."""
    return policy & ~_reset_on_fork()


def thread_policy(native_id: int) -> int:
    """The scheduling policy of thread ``native_id`` without the reset-on-fork flag (OSError, Unsupported)."""
    return policy_kind(_os_call("sched_getscheduler")(native_id))


def thread_policy_raw(native_id: int) -> int:
    """The scheduling policy of thread ``native_id`` as the system reports it, flags included."""
    return _os_call("sched_getscheduler")(native_id)


def thread_rt_priority(native_id: int) -> int:
    """The real-time priority of thread ``native_id`` (0 for ordinary threads)."""
    return _os_call("sched_getparam")(native_id).sched_priority


def set_thread_policy(native_id: int, policy: int) -> None:
    """Thread ``native_id`` back to ``policy`` (as :func:`thread_policy_raw` reported it) at priority 0."""
    _os_call("sched_setscheduler")(native_id, policy, _os_call("sched_param")(0))


def set_nice(native_id: int, nice: int) -> None:
    """The nice value of the calling process (``native_id`` 0, POSIX) or of one of its threads (its native id:
    Linux only, where a thread id is what setpriority takes; macOS' thread ids are no process ids and must
    never reach it). Raises OSError where not permitted, :class:`Unsupported` where there is no such call
    (Windows; a thread on macOS): the thread or process stays as it is."""
    if native_id != 0 and not is_linux():
        raise Unsupported(errno.ENOSYS, f"no nice value per thread on {sys.platform}")
    _os_call("setpriority")(_os_call("PRIO_PROCESS"), native_id, nice)


def get_nice(native_id: int = 0) -> int:
    """The nice value of thread or process ``native_id`` (:class:`Unsupported` on Windows)."""
    return _os_call("getpriority")(_os_call("PRIO_PROCESS"), native_id)


THREAD_SET_INFORMATION = 0x0020
THREAD_PRIORITY_TIME_CRITICAL = 15  # in the normal priority class: base priority 15, ahead of every ordinary thread
ABOVE_NORMAL_PRIORITY_CLASS = 0x8000


def _kernel32():
    """Windows' kernel32 through ctypes (tests replace this with a stand-in)."""
    import ctypes

    return ctypes.WinDLL("kernel32", use_last_error=True)


def _win_error(call: str) -> OSError:
    import ctypes

    code = ctypes.get_last_error() if hasattr(ctypes, "get_last_error") else 0
    return OSError(errno.EPERM, f"{call} failed (Windows error {code})")


def set_thread_time_critical(native_id: int) -> None:
    """Windows: thread ``native_id`` at THREAD_PRIORITY_TIME_CRITICAL within the process's class, which any
    user may set: the keep-alive sender runs as soon as its sleep ends, ahead of every ordinary thread of the
    machine. Only for threads that sleep between short sends (as on Linux' real-time policy). OSError when
    Windows refuses; :class:`Unsupported` on every other system."""
    if not is_windows():
        raise Unsupported(errno.ENOSYS, f"no Windows thread priorities on {sys.platform}")
    kernel32 = _kernel32()
    handle = kernel32.OpenThread(THREAD_SET_INFORMATION, False, native_id)
    if not handle:
        raise _win_error("OpenThread")
    try:
        if not kernel32.SetThreadPriority(handle, THREAD_PRIORITY_TIME_CRITICAL):
            raise _win_error("SetThreadPriority")
    finally:
        kernel32.CloseHandle(handle)


def set_process_above_normal() -> None:
    """Windows: this process in the ABOVE_NORMAL priority class (any user may set it; Windows' counterpart of
    a nice value of about -5). OSError when refused, :class:`Unsupported` on every other system."""
    if not is_windows():
        raise Unsupported(errno.ENOSYS, f"no Windows priority classes on {sys.platform}")
    kernel32 = _kernel32()
    if not kernel32.SetPriorityClass(kernel32.GetCurrentProcess(), ABOVE_NORMAL_PRIORITY_CLASS):
        raise _win_error("SetPriorityClass")


def real_time_bounded() -> bool:
    """Whether real-time threads that may not sleep still leave the machine usable: Linux with two CPUs or
    more and the kernel's real-time throttling on (``sched_rt_runtime_us`` below ``sched_rt_period_us``).
    False on every other system (they have no such policy for a program to use)."""
    if not is_linux():
        return False
    try:
        if (os.cpu_count() or 1) < 2:
            return False
        with open("/proc/sys/kernel/sched_rt_runtime_us") as f:
            runtime = int(f.read())
        with open("/proc/sys/kernel/sched_rt_period_us") as f:
            period = int(f.read())
        return 0 <= runtime < period
    except (OSError, ValueError):
        return False


def raise_session_group(nice: int) -> None:
    """Linux with autogroups (``kernel.sched_autogroup_enabled``): the scheduler first shares the CPU between
    sessions, and a thread's nice value counts only within its own; a process that leads its own session
    (started as a service or by a program, not from a shell whose session it would raise with it) raises
    its session's share too. Silently nothing where that is not permitted or not there (every other system)."""
    if not is_linux():
        return
    try:
        if os.getsid(0) != os.getpid():
            return
        with open("/proc/self/autogroup") as f:
            current = int(f.read().rsplit("nice", 1)[1])
        if current > nice:
            with open("/proc/self/autogroup", "w") as f:
                f.write(str(nice))
    except (OSError, ValueError, IndexError, AttributeError):
        pass


# -- the C allocator ---------------------------------------------------------------------------------------------

def heap_trimmer():
    """glibc's ``malloc_trim`` as a callable, or None: a C library without it (musl) and every system but
    Linux (Windows' and macOS' allocators give pages back on their own terms; nothing is trimmed there)."""
    if not is_linux():
        return None
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("c")
    if not name:
        return None
    try:
        function = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    function.argtypes = [ctypes.c_size_t]
    function.restype = ctypes.c_int
    return function


# -- the kernel's drop counters (the bus monitor's "lost by the interface") ----------------------------------------

SO_MEMINFO = 55  # Linux: the socket's memory figures, sk_drops among them (socket.SO_MEMINFO where Python names it)
SK_MEMINFO_DROPS = 8


def socket_drops(sock) -> int | None:
    """The kernel's drop counter of ``sock`` from one getsockopt (Linux 4.7+; the figure /proc/net/udp shows),
    or None where the system does not give it (every other system)."""
    if not is_linux():
        return None
    import socket

    try:
        raw = sock.getsockopt(socket.SOL_SOCKET, getattr(socket, "SO_MEMINFO", SO_MEMINFO), 64)
    except OSError:
        return None
    if len(raw) < 4 * (SK_MEMINFO_DROPS + 1):
        return None
    return struct.unpack_from("I", raw, 4 * SK_MEMINFO_DROPS)[0]


def udp_drops(inode: int) -> int | None:
    """The kernel's drop counter of the UDP socket with ``inode`` (last column of /proc/net/udp[6]); None
    where it is not listed or the system has no /proc (every system but Linux)."""
    if not is_linux():
        return None
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            with open(table) as f:
                next(f, None)
                for line in f:
                    parts = line.split()
                    if len(parts) >= 13 and parts[9] == str(inode):
                        return int(parts[12])
        except OSError:
            continue
    return None


def netdev_drops(interface: str) -> int | None:
    """A SocketCAN network interface's ``rx_dropped + rx_over_errors + rx_fifo_errors`` from /sys (Linux;
    blocking: call it in a thread), or None."""
    if not is_linux():
        return None
    folder = f"/sys/class/net/{os.path.basename(interface)}/statistics"
    total = 0
    try:
        for name in ("rx_dropped", "rx_over_errors", "rx_fifo_errors"):
            with open(f"{folder}/{name}") as f:
                total += int(f.read().strip() or 0)
    except (OSError, ValueError):
        return None
    return total


# -- single key presses at a terminal ----------------------------------------------------------------------------

class TerminalKeys:
    """Single key presses from the terminal on ``stream`` (standard input), read in a thread of their own and
    handed to ``on_key`` in the event loop that called :meth:`start`.

    POSIX: the terminal in cbreak mode (termios, restored at :meth:`stop`), waited on with select. Windows:
    the console's key buffer (``msvcrt.kbhit``/``getwch``, which read single keys without any mode),
    looked at every :data:`WINDOWS_POLL_S`."""

    WINDOWS_POLL_S = 0.02

    def __init__(self, stream=None):
        self.stream = sys.stdin if stream is None else stream
        self._thread = None
        self._running = False
        self._saved = None

    def start(self, on_key) -> None:
        import asyncio
        import threading

        loop = asyncio.get_running_loop()
        self._running = True
        read = self._windows_reader(loop, on_key) if is_windows() else self._posix_reader(loop, on_key)
        self._thread = threading.Thread(target=read, name="terminal keys", daemon=True)
        self._thread.start()

    def _posix_reader(self, loop, on_key):
        import termios
        import tty

        fd = self.stream.fileno()
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)

        def read() -> None:
            import select

            while self._running:
                ready, _, _ = select.select([fd], [], [], 0.1)
                if not ready:
                    continue
                data = os.read(fd, 32)
                if not data:
                    break
                for char in data.decode(errors="replace"):
                    loop.call_soon_threadsafe(on_key, char)

        return read

    def _windows_reader(self, loop, on_key):
        import msvcrt
        import time

        def read() -> None:
            while self._running:
                if not msvcrt.kbhit():
                    time.sleep(self.WINDOWS_POLL_S)
                    continue
                char = msvcrt.getwch()
                if char in ("\x00", "\xe0"):  # a function or arrow key: its second code follows, no key of ours
                    msvcrt.getwch()
                    continue
                loop.call_soon_threadsafe(on_key, char)

        return read

    def stop(self) -> None:
        self._running = False
        if self._thread is not None:
            self._thread.join(0.5)
        if self._saved is not None:
            import termios

            termios.tcsetattr(self.stream.fileno(), termios.TCSADRAIN, self._saved)
            self._saved = None
