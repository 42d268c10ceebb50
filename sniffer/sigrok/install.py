"""``xac1 sigrok install``: copy the XA-C1 decoder where libsigrokdecode looks for a user's decoders, and
take only it away again.

How this works. libsigrokdecode (0.5, Debian's) searches, besides its own folder, the user's data
folder: ``$XDG_DATA_HOME/libsigrokdecode/decoders``, that is ``~/.local/share/libsigrokdecode/decoders``
when ``XDG_DATA_HOME`` is not set (glib's ``g_get_user_data_dir``). Each decoder is a folder named
after it; ours is ``xac1/`` with the files of ``sniffer/sigrok/xac1`` (each carries the mark line
``pdgen.MARK``). Install writes a file only when it differs (a temporary name, then a rename), so a
second install changes nothing; a file of the folder that lacks our mark stops the install with a
message and nothing changed. Uninstall removes our files, the ``__pycache__`` the embedded Python
leaves, and the folder when it is then empty; anything else stays.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from .pdgen import DECODER_ID, FILES, MARK, shipped_dir

PULSEVIEW_HINT: Final = ("PulseView: restart it, add the UART decoder (Baud rate 9600, 8N1; RX and TX on the "
                         "lines), then stack XA-C1 on it (click the UART trace's name > Stack decoder > "
                         "XA-C1); its option 'host' says which UART line (tx or rx) is the host's")
CLI_HINT: Final = ("sigrok-cli: sigrok-cli -i CAPTURE -P uart:baudrate=9600:rx=device:tx=host,xac1 -A xac1"
                   "   (rx=, tx=: your channel names)")


class InstallError(Exception):
    """Why the install (or uninstall) could not be done; nothing was changed when raised."""


def decoders_dir(env: Mapping[str, str] | None = None) -> Path:
    """The user's decoder folder that libsigrokdecode searches, for ``env`` (default: this process's)."""
    env = os.environ if env is None else env
    xdg = env.get("XDG_DATA_HOME")
    if xdg and os.path.isabs(xdg):  # glib ignores a relative XDG_DATA_HOME
        return Path(xdg) / "libsigrokdecode" / "decoders"
    home = Path(env.get("HOME") or Path.home())
    return home / ".local" / "share" / "libsigrokdecode" / "decoders"


def decoder_dir(env: Mapping[str, str] | None = None) -> Path:
    """Where ``install`` puts the decoder's folder."""
    return decoders_dir(env) / DECODER_ID


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise InstallError(f"cannot read {path}: {exc}") from None


def _foreign(folder: Path) -> list[Path]:
    """Files of ``folder`` that are not ours (the embedded Python's ``__pycache__`` aside)."""
    if not folder.is_dir():
        return []
    out = []
    for path in sorted(folder.iterdir()):
        if path.name == "__pycache__":
            continue
        text = _read(path) if path.is_file() else None
        if text is None or MARK not in text:
            out.append(path)
    return out


def _write_atomic(path: Path, text: str) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as exc:
        raise InstallError(f"cannot write in {path.parent}: {exc.strerror or exc}; nothing was "
                           f"changed there") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise InstallError(f"cannot write {path}: {exc.strerror or exc}; it was left as it was") from None


def install(folder: Path) -> list[str]:
    """Copy the decoder into ``folder`` (``decoder_dir()``); what was done, a line each."""
    theirs = _foreign(folder)
    if theirs:
        raise InstallError(f"{theirs[0]} was not written by xac1: {folder} was left as it is (move it away "
                           f"to install ours)")
    if folder.exists() and not folder.is_dir():
        raise InstallError(f"{folder} is a file, not a folder: left as it is (move it away to install ours)")
    source = shipped_dir()
    changed = []
    for name in FILES:
        text = (source / name).read_text(encoding="utf-8")
        if _read(folder / name) != text:
            _write_atomic(folder / name, text)
            changed.append(name)
    stale = folder / "__pycache__"
    if changed and stale.is_dir():  # compiled from the old files: let Python compile ours again
        shutil.rmtree(stale, ignore_errors=True)
    if changed:
        return [f"decoder xac1: {folder} ({', '.join(changed)} written)"]
    return [f"decoder xac1: {folder} (already up to date)"]


def uninstall(folder: Path) -> list[str]:
    """Remove only what ``install`` put in ``folder``; what was done, a line each."""
    if not folder.is_dir():
        return [f"nothing of xac1 was installed there ({folder} does not exist)"]
    done: list[str] = []
    theirs = set(_foreign(folder))
    for path in sorted(folder.iterdir()):
        if path in theirs:
            done.append(f"{path}: not ours, left as it is")
            continue
        try:
            if path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink()
        except OSError as exc:
            raise InstallError(f"cannot remove {path}: {exc.strerror or exc}") from None
    if not theirs:
        try:
            folder.rmdir()
        except OSError as exc:
            raise InstallError(f"cannot remove {folder}: {exc.strerror or exc}") from None
    if theirs:
        done.insert(0, f"decoder xac1 removed from {folder} (the folder stays: it holds files not ours)")
    else:
        done.insert(0, f"decoder xac1 removed: {folder}")
    return done
