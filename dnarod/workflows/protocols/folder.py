"""A protocol's output folder remembers the settings its members were run with (``protocol.json``).

Running a protocol again into the same folder with the same settings reuses its finished members (more
turn or force values are added to the curve); with other settings (another source, time, temperature, salt,
start, ...) it is refused with one line naming what changed, unless ``--overwrite`` (then the members are
run again with the new settings), as an ensemble folder of another spec is refused. The check is made by
:func:`dnarod.workflows.protocols.run_protocol` (the command line and the Python API alike).
"""
from __future__ import annotations

import json
from pathlib import Path

from dnarod.core.errors import DnarodError

MANIFEST = "protocol.json"
#: Names that mark a protocol's folder (any of them; a protocol run stopped early may have only its members).
#: Any other non-empty folder is refused (:func:`dnarod.core.io.check_output_folder`).
PROTOCOL_MARKERS = (MANIFEST, "curve.csv", "members", "ensemble")


def _describe(key, old, new):
    return f"{key} {old!r} -> {new!r}"


def check_protocol_folder(out, kind, settings, overwrite=False):
    """Refuse ``out`` if it holds a protocol run with another ``kind`` or other ``settings`` (a JSON-safe
    dict of the settings shared by every member), unless ``overwrite``. A setting recorded as None counts as
    not given. Nothing is written."""
    p = Path(out) / MANIFEST
    if not p.is_file():
        return
    try:
        old = json.loads(p.read_text())
        old_kind, old_settings = old["kind"], old["settings"]
    except (OSError, ValueError, KeyError, TypeError):
        raise DnarodError(f"{p}: not a readable protocol record; choose another -o folder (or remove the file)") \
            from None
    if not isinstance(old_settings, dict):
        raise DnarodError(f"{p}: not a readable protocol record; choose another -o folder (or remove the file)")
    # a setting recorded as None and one not recorded are the same (records of settings since removed stay valid)
    same = all(old_settings.get(k) == settings.get(k) for k in set(old_settings) | set(settings))
    if overwrite or (old_kind == kind and same):
        return
    if old_kind != kind:
        what = f"a {old_kind} run, not {kind}"
    else:
        keys = sorted(set(old_settings) | set(settings))
        what = f"a {kind} run made with other settings (" + "; ".join(_describe(k, old_settings.get(k), settings.get(k)) for k in keys
                                             if old_settings.get(k) != settings.get(k)) + ")"
    raise DnarodError(f"{out}: holds {what}; choose another -o folder, or pass --overwrite to run its members "
                      f"again with these settings")


def write_protocol_record(out, kind, settings):
    """Record ``kind`` and ``settings`` in ``out/protocol.json`` (atomically)."""
    from dnarod.core.io import write_text_atomic

    write_text_atomic(Path(out) / MANIFEST, json.dumps({"format": "dnarod-protocol", "kind": kind,
                                                        "settings": settings}, indent=1, sort_keys=True) + "\n")


def replaces_other_settings(out, kind, settings):
    """True if ``out`` holds a protocol record of another ``kind`` or other ``settings`` (an ``--overwrite``
    then makes the new run beside it: :func:`dnarod.workflows.protocols.run_protocol`)."""
    p = Path(out) / MANIFEST
    if not p.is_file():
        return False
    try:
        old = json.loads(p.read_text())
        return (old["kind"], old["settings"]) != (kind, settings)
    except (OSError, ValueError, KeyError, TypeError):
        return True


#: What a protocol writes into its folder (an ``--overwrite`` with other settings replaces exactly these).
PROTOCOL_FILES = (MANIFEST, "curve.csv", "curve.png", "members.csv", "members", "ensemble", "ladders")
