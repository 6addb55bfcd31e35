"""The files a run writes (``--report``, ``--plot``, ``--record``), for the
commands that run a mission (``zarco sim``, ``zarco hil``): checked before the
run starts, written after it, and named afterwards only if they were written.

A path that cannot be used is refused before the run (:class:`PathError`,
exit 2).  A file that fails later all the same (a full disk) is reported in
one line each after the run's summary, and the command exits 1: the summary
is printed whatever happens, so a run's figures are never lost to a file.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zarco_core.paths import PathError, oserror_reason, writable_file, write_text


@dataclass(slots=True)
class RunOutputs:
    """The output files of one run, checked (see :meth:`check`)."""

    report: Path | None = None
    plot: Path | None = None
    record: Path | None = None
    #: what was written, as the lines naming it ("report: FILE")
    written: list[str] = field(default_factory=list)
    #: one line per file that could not be written
    failed: list[str] = field(default_factory=list)

    @classmethod
    def check(cls, report: str | None, plot: str | None,
              record: str | None = None) -> RunOutputs:
        """Check the paths before a run (raises PathError naming the option)."""
        rep = writable_file(report, "--report") if report else None
        img = None
        if plot:
            from zarco_tools.plot import image_path

            img = image_path(plot, "--plot")
        rec = writable_file(record, "--record") if record else None
        paths = [("--report", rep), ("--plot", img), ("--record", rec)]
        seen: dict[Path, str] = {}
        for opt, p in paths:
            if p is None:
                continue
            key = p.resolve()
            if key in seen:
                raise PathError(p, f"also given to {seen[key]}: one file each", opt)
            seen[key] = opt
        return cls(rep, img, rec)

    def write_report(self, report: dict[str, Any]) -> None:
        """Write the JSON report (whole, or not at all)."""
        if self.report is None:
            return
        try:
            write_text(self.report, json.dumps(report, indent=2) + "\n", "--report")
            self.written.append(f"report: {self.report}")
        except PathError as exc:
            self.failed.append(str(exc))

    def write_plot(self, draw: Callable[[Path], None]) -> None:
        """Draw the plot into its file with ``draw(path)``."""
        if self.plot is None:
            return
        try:
            draw(self.plot)
            self.written.append(f"plot:   {self.plot}")
        except OSError as exc:
            self.failed.append(f"--plot: {self.plot}: cannot write it: {oserror_reason(exc)}")

    def recorded(self, paths: list[str], error: str | None) -> None:
        """What the recorder wrote (``paths``, its files in order) and why it
        stopped early (``error``), if it did."""
        if self.record is None:
            return
        files = [p for p in paths if Path(p).is_file()]
        if files:
            more = f" (+ {len(files) - 1} more parts: {', '.join(files[1:])})" \
                if len(files) > 1 else ""
            note = " (incomplete: recording failed)" if error else ""
            self.written.append(f"record: {files[0]}{more}{note}")
        if error:
            self.failed.append(f"--record: {self.record}: recording failed: {error}")
