"""The one reader of results files (``silo report``, demos, benchmarks and tests use it).

:func:`read_csv` gives a CSV as columns, typed by its schema (:mod:`.schema`): numbers as
float arrays (empty cells NaN), text columns as string arrays. :func:`read_rows` gives the
rows as the strings on disk, for checks on the file itself. Both check the header against
the schema, so a renamed column fails loudly here, not as a KeyError later (a column the
file lacks — an older results folder — is simply absent).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from silo_dolfinx.output.schema import for_file


def _load(path: Path) -> list[list[str]] | None:
    if not path.is_file():
        return None
    with open(path) as f:
        rows = list(csv.reader(f))
    if rows:
        schema = for_file(path.name)
        unknown = [c for c in rows[0] if schema is not None and c not in schema.names]
        if unknown:
            raise ValueError(f"{path}: columns {unknown} are not in the schema of {schema.pattern} "
                             f"({schema.names}): a results folder from another version? Re-run the scene.")
    return rows


def read_csv(path: str | Path) -> dict[str, np.ndarray] | None:
    """A results CSV as {column: array}; None if the file is missing or has no data row."""
    rows = _load(Path(path))
    if rows is None or len(rows) < 2:
        return None
    head, body = rows[0], rows[1:]
    schema = for_file(Path(path).name)
    text = {c.name for c in schema.columns if c.text} if schema is not None else set()
    cols = {}
    for j, name in enumerate(head):
        vals = [r[j] if j < len(r) else "" for r in body]
        if name in text:
            cols[name] = np.array(vals)
            continue
        try:
            cols[name] = np.array([float(v) if v != "" else np.nan for v in vals])
        except ValueError:  # a file without a schema: a text column
            cols[name] = np.array(vals)
    return cols


def read_rows(path: str | Path) -> list[dict[str, str]]:
    """The data rows of a results CSV as {column: string on disk} ([] if missing or empty)."""
    rows = _load(Path(path))
    if not rows:
        return []
    return [dict(zip(rows[0], r)) for r in rows[1:]]


def read_summary(folder: str | Path) -> dict:
    """summary.json of a results folder ({} if there is none yet)."""
    p = Path(folder) / "summary.json"
    return json.loads(p.read_text()) if p.is_file() else {}
