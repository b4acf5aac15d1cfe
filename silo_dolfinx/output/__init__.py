"""Everything a run writes, and the one way to read it back.

* :mod:`.schema` — one schema per results file (columns, units, meaning);
* :mod:`.writer` — the results folder (:class:`Results`), CSV series, progress lines;
* :mod:`.streams` — the output streams of a running model (energy and wall histories, wall
  profiles, VTX fields, the outlet and mesh-quality monitor), each built only when asked for;
* :mod:`.reader` — :func:`read_csv`, :func:`read_rows`, :func:`read_summary`.
"""

from silo_dolfinx.output.reader import read_csv, read_rows, read_summary
from silo_dolfinx.output.writer import CsvSeries, Progress, Results

__all__ = ["CsvSeries", "Progress", "Results", "read_csv", "read_rows", "read_summary"]
