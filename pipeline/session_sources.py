"""Where a recording's session metadata and topic-to-placement mapping come from.

Session fields (study, participant, session, kind, protocol, trial, timezone, ...) are gathered from,
in this order:

1. the MCAP ``session`` metadata record;
2. rosbag2 custom data ``session.<field>`` (``metadata.yaml`` ``custom_data`` of a bag directory, or
   the ``rosbag2`` metadata record inside an MCAP file that travels without its bag directory), e.g.
   ``ros2 bag record -s mcap --custom-data session.study=gait2026 ...``;
3. a sidecar TOML file ``<recording>.session.toml`` beside the file or bag directory, or
   ``session.toml`` inside a bag directory (top-level keys or a ``[session]`` table);
4. ``stridelab ingest/run --session FIELD=VALUE``.

Sources complete each other; a field given by two sources with different values is an error (the
reason names the field and the two sources, never the values). Topics map to placements by name
(``/imu/<placement>``, ``/mag/<placement>``), or explicitly with ``--topic-map TOPIC=PLACEMENT`` and the
study manifest's ``[topics]`` table (the command line wins over the manifest).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

SESSION_PREFIX = "session."


class SessionSourceError(ValueError):
    """Session metadata cannot be assembled; ``str(err)`` is the one-line reason."""


def parse_assignments(values, what: str) -> dict[str, str]:
    """``["A=B", ...]`` (command-line options) -> ``{"A": "B"}``; raises ValueError with a clear reason."""
    out: dict[str, str] = {}
    for v in values or ():
        key, sep, val = str(v).partition("=")
        key, val = key.strip(), val.strip()
        if not sep or not key or not val:
            raise ValueError(f"{what} expects KEY=VALUE, got '{str(v)[:60]}'")
        if key in out and out[key] != val:
            raise ValueError(f"{what} gives '{key}' twice with different values")
        out[key] = val
    return out


def sidecar_paths(path: Path) -> list[Path]:
    """Sidecar files that may hold session metadata for a recording file or bag directory."""
    path = Path(path)
    name = path.name[:-len(path.suffix)] if path.is_file() and path.suffix else path.name
    out = [path.with_name(f"{name}.session.toml")]
    if path.is_dir():
        out.append(path / "session.toml")
    return [p for p in out if len(p.name.encode()) <= 255]     # a longer sidecar name cannot exist (issue #47)


def read_sidecar(p: Path) -> dict[str, str]:
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SessionSourceError(f"sidecar {p.name} is not valid TOML ({str(e).splitlines()[0][:80]}); fix it") from None
    if isinstance(doc.get("session"), dict):
        doc = doc["session"]
    bad = [k for k, v in doc.items() if isinstance(v, (dict, list))]
    if bad:
        raise SessionSourceError(f"sidecar {p.name}: field '{bad[0]}' must be a plain value")
    return {str(k): str(v) for k, v in doc.items()}


def gather_session(path: Path, metadata: dict[str, dict[str, str]], custom_data: dict[str, str],
                   cli: dict[str, str] | None) -> tuple[dict[str, str], list[str]]:
    """Merged session fields and the names of the sources that contributed (in precedence order)."""
    sources: list[tuple[str, dict[str, str]]] = []
    if "session" in metadata:
        sources.append(("the MCAP 'session' record", dict(metadata["session"])))
    cd = {k[len(SESSION_PREFIX):]: v for k, v in (custom_data or {}).items() if k.startswith(SESSION_PREFIX)}
    if cd:
        sources.append(("rosbag2 custom data", cd))
    for p in sidecar_paths(path):
        if p.is_file():
            sources.append((f"sidecar {p.name}", read_sidecar(p)))
    if cli:
        sources.append(("--session", dict(cli)))
    merged: dict[str, str] = {}
    origin: dict[str, str] = {}
    for name, fields in sources:
        for k, v in fields.items():
            v = str(v)       # not stripped: 'P001\n' must reach the identifier check and be refused, not become P001
            if k in merged and merged[k].strip() != v.strip():
                raise SessionSourceError(f"session field '{k}' differs between {origin[k]} and {name}; "
                                         f"make the sources agree")
            if k not in merged:
                merged[k], origin[k] = v, name
    return merged, [n for n, _ in sources]


NO_SESSION = ("no session metadata (study, participant, session, kind): add an MCAP 'session' record, rosbag2 "
              "custom data (ros2 bag record --custom-data session.study=...), a sidecar <name>.session.toml, "
              "or --session FIELD=VALUE")


def placement_for(topic: str, kind: str, topic_map: dict[str, str]) -> tuple[str, str] | None:
    """(placement, series name prefix) of a decoded topic, or None when it maps to no placement."""
    if topic in topic_map and kind in ("imu", "mag", "reference_pose"):
        return topic_map[topic], kind
    parts = topic.strip("/").split("/")
    if kind == "imu" and topic.startswith("/imu/") and len(parts) == 2:
        return parts[1], "imu"
    if kind == "mag" and topic.startswith("/mag/") and len(parts) == 2:
        return parts[1], "mag"
    if kind == "reference_pose" and topic.startswith("/reference/pose/") and len(parts) == 3:
        return parts[2], "reference_pose"
    if kind == "range" and topic.startswith("/range/") and len(parts) in (2, 3):
        return parts[1], f"range-{parts[2] if len(parts) > 2 else 'A'}"
    return None
