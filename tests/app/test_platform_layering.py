"""Calls that only some systems have are made in app/host.py alone, each with its fallback there.

The product code (app/, devices/, pages/, server/) is parsed, not imported: a call that Windows or macOS
lacks (or that means nothing there) anywhere else fails this test with its file and line, and the place to
put it is app/host.py (docs/windows-macos.md lists what each system gets instead).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("app", "devices", "pages", "server")
PLATFORM_MODULE = ROOT / "app" / "host.py"

# modules only POSIX (or only Windows) has, or whose use is one system's
FORBIDDEN_MODULES = {"fcntl", "termios", "tty", "resource", "pwd", "grp", "msvcrt", "winreg", "_winapi", "posix", "nt"}
# os.<name>: POSIX- or Linux-only calls, or modes used as protection
FORBIDDEN_OS = {"setpriority", "getpriority", "nice", "chmod", "fchmod", "lchmod", "umask", "getsid", "setsid",
                "getuid", "geteuid", "getgid", "fork", "killpg", "getpgid", "setpgid", "sched_param", "PRIO_PROCESS",
                "chown", "fchown", "lchown", "mkfifo", "statvfs"}
FORBIDDEN_OS_PREFIXES = ("sched_", "SCHED_")
# attributes of any object: the loop's signal handlers, a path's mode, the Linux socket option, glibc's trim
FORBIDDEN_ATTRIBUTES = {"add_signal_handler", "remove_signal_handler", "chmod", "lchmod", "SO_MEMINFO", "malloc_trim", "prctl"}
FORBIDDEN_NAMES = {"SO_MEMINFO", "malloc_trim", "prctl"}
FORBIDDEN_SIGNAL = {"signal", "siginterrupt", "pthread_kill", "pthread_sigmask", "setitimer", "alarm", "pause",
                    "SIGHUP", "SIGUSR1", "SIGUSR2", "SIGKILL", "SIGALRM", "SIGCHLD", "SIGBREAK", "set_wakeup_fd"}
FORBIDDEN_PATH_PREFIXES = ("/proc", "/sys/", "/dev/shm")
FORBIDDEN_STRINGS = {"malloc_trim", "SO_MEMINFO", "prctl"}


def _product_files() -> list[Path]:
    return sorted(p for folder in PRODUCT for p in (ROOT / folder).rglob("*.py") if p != PLATFORM_MODULE)


def _dotted(node: ast.AST) -> str:
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
    return ".".join(reversed(parts))


def _string_start(node: ast.AST) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr) and node.values and isinstance(node.values[0], ast.Constant):
        return str(node.values[0].value)
    return None


def platform_calls(source: str, filename: str = "<source>") -> list[str]:
    """``line: what`` for every POSIX- or Linux-only call in ``source``."""
    tree = ast.parse(source, filename)
    found: list[tuple[int, str]] = []
    os_names = {"os"}  # names the module os is bound to (import os as _os)
    signal_names = {"signal"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                top = alias.name.split(".")[0]
                if top in FORBIDDEN_MODULES:
                    found.append((node.lineno, f"import {alias.name}"))
                if alias.name == "os":
                    os_names.add(alias.asname or "os")
                if alias.name == "signal":
                    signal_names.add(alias.asname or "signal")
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            top = node.module.split(".")[0]
            names = {a.name for a in node.names}
            if top in FORBIDDEN_MODULES:
                found.append((node.lineno, f"from {node.module} import ..."))
            elif node.module == "os" and (bad := {n for n in names if n in FORBIDDEN_OS or n.startswith(FORBIDDEN_OS_PREFIXES)}):
                found.append((node.lineno, f"from os import {', '.join(sorted(bad))}"))
            elif node.module == "signal" and (bad := names & FORBIDDEN_SIGNAL):
                found.append((node.lineno, f"from signal import {', '.join(sorted(bad))}"))
            elif node.module == "socket" and "SO_MEMINFO" in names:
                found.append((node.lineno, "from socket import SO_MEMINFO"))
        elif isinstance(node, ast.Attribute):
            base = node.value.id if isinstance(node.value, ast.Name) else None
            if base in os_names and (node.attr in FORBIDDEN_OS or node.attr.startswith(FORBIDDEN_OS_PREFIXES)):
                found.append((node.lineno, f"os.{node.attr}"))
            elif base in signal_names and node.attr in FORBIDDEN_SIGNAL:
                found.append((node.lineno, f"signal.{node.attr}"))
            elif node.attr in FORBIDDEN_ATTRIBUTES:
                found.append((node.lineno, _dotted(node) or node.attr))
        elif isinstance(node, ast.Name) and node.id in FORBIDDEN_NAMES:
            found.append((node.lineno, node.id))
        else:
            text = _string_start(node)
            if text is not None:
                stripped = text.strip()
                if stripped.startswith(FORBIDDEN_PATH_PREFIXES) and "\n" not in stripped:
                    found.append((node.lineno, f"path {stripped[:40]!r}"))
                elif stripped in FORBIDDEN_STRINGS:
                    found.append((node.lineno, f"name {stripped!r}"))
    return [f"{line}: {what}" for line, what in sorted(set(found))]


def test_no_posix_or_linux_only_call_outside_the_platform_module():
    offences = []
    for path in _product_files():
        for hit in platform_calls(path.read_text(encoding="utf-8"), str(path)):
            offences.append(f"{path.relative_to(ROOT)}:{hit}")
    assert not offences, ("POSIX- or Linux-only calls outside app/host.py (put each there, with its fallback for "
                          "Windows and macOS, and list it in docs/windows-macos.md):\n  " + "\n  ".join(offences))


@pytest.mark.parametrize("source", [
    "import os\nos.sched_setscheduler(0, os.SCHED_RR, os.sched_param(1))",
    "import os\nos.setpriority(os.PRIO_PROCESS, 0, -5)",
    "import os as _os\n_os.chmod('x', 0o600)",
    "from pathlib import Path\nPath('x').chmod(0o600)",
    "import fcntl",
    "import termios",
    "from tty import setcbreak",
    "import resource",
    "import msvcrt",
    "open('/proc/self/status')",
    "open(f'/sys/class/net/{name}/statistics')",
    "import socket\nsocket.SO_MEMINFO",
    "getattr(socket, 'SO_MEMINFO', 55)",
    "ctypes.CDLL(None).prctl(1, 15)",
    "libc.malloc_trim(0)",
    "loop.add_signal_handler(2, stop.set)",
    "import signal\nsignal.signal(signal.SIGINT, handler)",
    "from signal import signal\n",
    "import os\nos.umask(0o077)",
    "import os\nos.getsid(0)",
])
def test_the_checker_finds_each_kind_of_call(source):
    assert platform_calls(source), source


@pytest.mark.parametrize("source", [
    "import os\nos.environ.get('X')\nos.replace('a', 'b')",
    "import signal\nsignal.SIGINT",
    "'a sentence that mentions /proc in passing'",
    "from app import host\nhost.protect_file('x')",
])
def test_the_checker_leaves_portable_code_alone(source):
    assert platform_calls(source) == []


def test_the_platform_module_itself_is_where_they_are():
    assert platform_calls(PLATFORM_MODULE.read_text(encoding="utf-8"))  # the checker would see them: they are here
