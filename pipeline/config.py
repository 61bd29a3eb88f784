"""Where things live and which parameters a study's stages use.

``STRIDELAB_HOME`` (default ``./stridelab-home``) holds ``inbox/``, ``warehouse/`` and ``reports/``.
Per-study stage parameters come from ``[stages.<name>]`` of the study manifest
(``studies/<study>/study.toml`` in the package, or ``$STRIDELAB_STUDIES/<study>/study.toml``) and
override the stage defaults key by key; ``[compute.<name>]`` (``<session kind> = true``) asks for a
stage's opt-in outputs (``pipeline/stages/__init__.py``).
"""
from __future__ import annotations

import os
import tomllib
from functools import lru_cache
from pathlib import Path

from stridelab.warehouse.location import default_warehouse, home  # noqa: F401  (one definition, shared with the dashboard)

PACKAGE_STUDIES = Path(__file__).resolve().parent.parent / "studies"


def default_inbox() -> Path:
    return home() / "inbox"


def default_reports() -> Path:
    return home() / "reports"


SESSION_KINDS = ("lab", "free_living", "calibration")


@lru_cache(maxsize=64)
def study_manifest(study: str) -> dict:
    """The study's manifest as a dict ({} when the study has none)."""
    dirs = [Path(d) for d in os.environ.get("STRIDELAB_STUDIES", "").split(os.pathsep) if d] + [PACKAGE_STUDIES]
    for d in dirs:
        for p in (d / study / "study.toml", d / study.lower() / "study.toml"):
            if p.is_file():
                try:
                    return tomllib.loads(p.read_text())
                except tomllib.TOMLDecodeError as e:
                    raise ValueError(f"{p}: invalid TOML ({e})") from None
    return {}


def stage_params(study: str, stage_name: str, defaults: dict) -> dict:
    """Stage defaults overridden by the study manifest's ``[stages.<stage_name>]`` table (key by key). An unknown
    key is refused here, nested tables included: the overrides must map onto the stage's frozen parameter class
    (``Stage.params_cls``, :func:`stridelab.pipeline.stages._shape.params_from_dict`)."""
    over = study_manifest(study).get("stages", {}).get(stage_name, {})
    unknown = set(over) - set(defaults)
    if unknown:
        raise ValueError(f"study {study}: unknown parameter(s) {sorted(unknown)} for stage {stage_name}; "
                         f"known: {sorted(defaults)}")
    merged = {**defaults, **over}
    cls = _params_cls(stage_name) if over else None
    if cls is not None:
        from stridelab.pipeline.stages._shape import params_from_dict
        try:
            params_from_dict(cls, merged)
        except ValueError as e:
            raise ValueError(f"study {study}: [stages.{stage_name}] {e}") from None
    return merged


def _params_cls(stage_name: str):
    """The frozen parameter class of the registered stage ``stage_name`` (None when it has none)."""
    from stridelab.pipeline import stages
    return next((s.params_cls for s in stages.registry() if s.name == stage_name), None)


def compute_requests(study: str) -> dict[str, dict[str, bool]]:
    """The manifest's ``[compute.<stage>]`` tables: stage -> {session kind: computed or not}."""
    req = study_manifest(study).get("compute", {})
    if not isinstance(req, dict) or not all(isinstance(v, dict) for v in req.values()):
        raise ValueError(f"study {study}: [compute] must hold [compute.<stage>] tables of <session kind> = true/false")
    for stage_name, kinds in req.items():
        bad = {k: v for k, v in kinds.items() if k not in SESSION_KINDS or not isinstance(v, bool)}
        if bad:
            raise ValueError(f"study {study}: [compute.{stage_name}] {bad} is not <session kind> = true/false "
                             f"(kinds: {', '.join(SESSION_KINDS)})")
    return req


def requested(study: str, stage_name: str, kind: str) -> bool:
    """Whether the study's manifest asks for ``stage_name`` on sessions of ``kind``."""
    return bool(compute_requests(study).get(stage_name, {}).get(kind, False))
