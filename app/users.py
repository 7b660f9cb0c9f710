"""User accounts with roles, stored with salted argon2 hashes in ``users.toml`` in the data folder."""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass
from pathlib import Path

import tomllib
from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

from app import host
from devices.errors import CommissionError

ROLES = ("engineer", "viewer")  # engineer: may write, drive, restore; viewer: reads only
LOOPBACK_HOSTS = {"127.0.0.1", "localhost", "::1"}
_hasher = PasswordHasher()


class UserError(CommissionError, ValueError):
    """A user name, role or password that cannot be used."""


def default_data_dir() -> Path:
    """Where accounts, the audit log and backups live unless ``--data-dir`` says otherwise:
    ``COMMISSION_DATA_DIR``, else the platform's user data folder (:func:`app.host.data_dir`)."""
    return host.data_dir()


@dataclass(frozen=True)
class User:
    name: str
    role: str
    password_hash: str


class UserStore:
    """The accounts file; written atomically, read on every change."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.users: dict[str, User] = {}
        self._stamp: tuple[int, int] | None = None
        self.load()

    def _file_stamp(self) -> tuple[int, int] | None:
        try:
            st = self.path.stat()
        except FileNotFoundError:
            return None
        return (st.st_mtime_ns, st.st_size)

    def load(self) -> None:
        stamp = self._file_stamp()
        users: dict[str, User] = {}
        if stamp is not None:
            try:
                data = tomllib.loads(self.path.read_text(encoding="utf-8"))
            except (OSError, tomllib.TOMLDecodeError) as exc:
                raise UserError(f"{self.path}: cannot read the accounts file: {exc}") from None
            except UnicodeDecodeError as exc:
                raise UserError(f"{self.path}: the accounts file is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} "
                                f"at offset {exc.start})") from None
            for entry in data.get("user", []):
                user = User(str(entry["name"]), str(entry["role"]), str(entry["hash"]))
                if user.role in ROLES:
                    users[user.name] = user
        self.users = users  # replaced whole: readers never see a half-read store
        self._stamp = stamp

    def reload_if_changed(self) -> bool:
        """Read the file again when another process (``commission user ...``) changed it."""
        if self._file_stamp() == self._stamp:
            return False
        self.load()
        return True

    def save(self) -> None:
        # the data folder is owner only from its first file on (``commission user add`` before the GUI ever ran)
        host.protect_folder(self.path.parent)
        lines = ["# commission accounts: manage with `commission user add NAME --role engineer|viewer`", ""]
        for user in sorted(self.users.values(), key=lambda u: u.name):
            lines += ["[[user]]", f'name = "{user.name}"', f'role = "{user.role}"', f'hash = "{user.password_hash}"', ""]
        tmp = self.path.with_suffix(".tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)  # never readable by others, not even briefly
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write("\n".join(lines))
        host.protect_file(tmp)
        tmp.replace(self.path)
        self._stamp = self._file_stamp()

    def add(self, name: str, role: str, password: str) -> User:
        if not re.fullmatch(r"[A-Za-z0-9_.@-]{1,64}", name):
            raise UserError("user names may contain letters, digits and _ . @ - (up to 64)")
        if role not in ROLES:
            raise UserError(f"role must be one of {', '.join(ROLES)}")
        if len(password) < 8:
            raise UserError("the password needs at least 8 characters")
        user = User(name, role, _hasher.hash(password))
        self.users[name] = user
        self.save()
        return user

    def remove(self, name: str) -> bool:
        if self.users.pop(name, None) is None:
            return False
        self.save()
        return True

    def verify(self, name: str, password: str) -> User | None:
        """The user when the password matches, else None (timing of a miss stays the same)."""
        user = self.users.get(name)
        try:
            _hasher.verify(user.password_hash if user else _dummy_hash(), password)
        except (VerificationError, InvalidHashError):
            return None
        return user

    def has_engineer(self) -> bool:
        return any(u.role == "engineer" for u in self.users.values())


@functools.cache
def _dummy_hash() -> str:
    """What a name nobody has is checked against, so that a miss takes as long as a wrong password. Made at the
    first miss, not at import: a hash costs 0.2-0.7 s of CPU, and every process that starts a plant (a command line
    run, the GUI) imports this module, most of them never checking a password."""
    return _hasher.hash("not a password of anyone")


def is_loopback(host: str) -> bool:
    return host in LOOPBACK_HOSTS or host.startswith("127.")
