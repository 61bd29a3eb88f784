"""Keyed pseudonymisation of site identifiers at ingest.

A recording may carry the site's own participant identifier (``site_id`` in the ``session``
metadata, e.g. a hospital number). It never reaches the warehouse: ingest replaces it by
``HMAC-SHA256(key, study:site_id)`` rendered as ``PS-`` + 12 base32 characters, and uses that as
the participant pseudonym. The key is a file *outside* the warehouse (``STRIDELAB_PSEUDONYM_KEY``,
default ``~/.config/stridelab/pseudonym.key``), so a copy of the warehouse alone cannot be linked
back to site records; the same key always gives the same pseudonym, so sessions of one person meet.
"""
from __future__ import annotations

import base64
import hashlib
import hmac
import os
import secrets
from pathlib import Path

SITE_KEYS = ("site_id", "site_participant_id")


def key_path() -> Path:
    return Path(os.environ.get("STRIDELAB_PSEUDONYM_KEY", "~/.config/stridelab/pseudonym.key")).expanduser()


def create_key(path: Path | None = None) -> Path:
    """Create a new random 256-bit key file (mode 600); refuses to overwrite an existing key."""
    p = Path(path) if path else key_path()
    p.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_hex(32) + "\n")
    return p


def load_key(warehouse_root: Path | None = None) -> bytes:
    p = key_path()
    if warehouse_root is not None:
        try:
            p.resolve().relative_to(Path(warehouse_root).resolve())
            raise ValueError(f"the pseudonymisation key {p} lies inside the warehouse; keep it elsewhere")
        except ValueError as e:
            if "inside the warehouse" in str(e):
                raise
    try:
        text = p.read_text().strip()
    except FileNotFoundError:
        raise ValueError(f"metadata carries a site identifier but no pseudonymisation key exists at {p}; "
                         f"create one with `stridelab pseudonym-key` (and back it up)") from None
    if len(text) < 32:
        raise ValueError(f"pseudonymisation key {p} is too short (need ≥ 32 hex characters)")
    return text.encode()


def pseudonym(key: bytes, study: str, site_id: str) -> str:
    digest = hmac.new(key, f"{study}:{site_id}".encode(), hashlib.sha256).digest()
    return "PS-" + base64.b32encode(digest).decode()[:12]


def pseudonymise(session: dict, warehouse_root: Path | None = None) -> dict:
    """Return the session metadata with any site identifier replaced by its keyed pseudonym."""
    site = next((session[k] for k in SITE_KEYS if session.get(k)), None)
    if site is None:
        return session
    out = {k: v for k, v in session.items() if k not in SITE_KEYS}
    out["participant"] = pseudonym(load_key(warehouse_root), session["study"], str(site))
    out["pseudonymised"] = "hmac-sha256"
    return out
