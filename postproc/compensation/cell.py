"""A robot cell as one unit: the files of one robot's programs or a controller backup directory
(``programs.cell``: a KRL cell or ``KRC/R1/``, a RAPID task or backup of tasks, a Fanuc LS
backup, several URScript programs or pose lists), each of its programs compensated on its own,
all written together (one atomic write, nothing if one is refused), the output tree mirroring
the input's; the report says per file what was compensated and left (``Report.files_summary``).

KRL: a cell or backup (``KRC/R1/``) → its modules (.src/.sub with their .dat), its data lists without a DEF, its
``$config.dat``; compensated together and written together (one atomic write of every
file, the journal of ``atomic.write_atomic``), the output tree mirroring the input's.

Reading: every file of the cell in one reader call (``programs.krl.read`` takes a set of
modules): ``$config.dat`` and PUBLIC data lists first, so that ``DECL GLOBAL`` points and
BASE_DATA/TOOL_DATA resolve across modules; each point is compensated in the frame of its
uses. A ``$config.dat`` inside the cell is one of its files (its global points can be
compensated and it is written with the others); one given from outside (``--config``) is
read only. A target whose point is declared in no file read is left as written with the
reader's located warning (P215), never compensated in a guessed frame.

The robot's place in $WORLD ($ROBROOT, the ``$ROBROOT_C`` of ``Mada/$machine.dat``) comes from
the machine data of the backup (``programs.krl.machine``): a ``$machine.dat`` among the files,
else ``Mada/$machine.dat`` of the directory (the shallowest below it), else the one beside the
``System/`` of the cell's ``$config.dat``; ``--robroot`` wins. Machine data is read, never
compensated or written.
"""
from __future__ import annotations

from pathlib import Path

from ..core.diagnostics import P110, PostprocError
from ..model.compensator import Compensator
from ..programs.cell import Cell
from ..settings import Settings
from .pipeline import Report, compensate_program, write_outputs

__all__ = ["compensate_cell"]


def compensate_cell(cell: Cell, out_dir: str | Path, model: Compensator, settings: Settings = Settings()) -> Report:
    """Compensate every module of ``cell`` (``settings`` as for ``compensate_program``) and
    write all its files below ``out_dir`` at their paths relative to ``cell.root``, all or
    none. Nothing is written if any module is refused (the first refusal is raised)."""
    out_dir = Path(out_dir)
    if out_dir.resolve() == cell.root.resolve() or cell.root.resolve().is_relative_to(out_dir.resolve()):
        raise PostprocError("-o is the cell's own directory: give another directory, the cell's files stay as "
                            "they are", str(out_dir), 0, 0, P110)
    if out_dir.exists() and not out_dir.is_dir():
        raise PostprocError("is not a directory: a cell is written to a directory (-o OUTDIR)", str(out_dir), 0, 0,
                            P110)
    if not cell.files:
        return Report(model=model.name, model_sha256=model.sha256)
    programs = cell.read_all(settings.reading.config_list, settings.reading.registers)
    report = Report.merged([compensate_program(program, model, settings) for program in programs])
    outputs: list[tuple[Path, str | bytes]] = [(out_dir / Path(name).resolve().relative_to(cell.root), text)
                                               for name, text in report.outputs.items()]
    write_outputs(outputs)
    report.written = [(name, str(path)) for name, (path, _) in zip(report.outputs, outputs)]
    return report
