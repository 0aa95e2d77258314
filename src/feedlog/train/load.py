"""Reading align's output folders into `ProgramTable`s, with split, profile and program from the manifest.

An aligned folder (`feedlog align ... -o OUT` writes OUT/<recording>/) holds `blocks.parquet` and
`points.parquet`. The recordings' `manifest.toml` (recordings/manifest.toml: `[[recording]]` tables
with `name`, `split`, `profile`, `program`, `family`) says which recordings are held out for testing.
It is found next to the recording named in the tables' metadata, or in a parent of the aligned folder
(or its `recordings/` subfolder), unless given explicitly. Sessions listed in `held_back.toml` beside
it (recorded alike, but kept out of the simulation's accuracy test because it misses them) are data
like the others: the learners train on them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from feedlog.errors import FeedlogError, ModelError
from feedlog.execution import TaskRunner
from feedlog.manifest import MANIFEST, ManifestEntry, with_held_back
from feedlog.profile import load_profile
from feedlog.train.dataset import ProgramTable

def _entries(manifest: Path) -> dict[str, ManifestEntry]:
    """A manifest's rows and those of the `held_back.toml` beside it; its errors as the learners' errors."""
    try:
        return with_held_back(manifest)
    except FeedlogError as exc:
        raise ModelError(str(exc)) from None


def _manifest_candidates(folder: Path, meta: dict[str, Any]) -> Iterable[Path]:
    # absolute first (a worker of `feedlog train -j/--scheduler` finds the same file wherever it runs),
    # then as given to align (relative to where it ran)
    for key in ("recording_path", "recording"):
        if meta.get(key):
            yield Path(meta[key]).parent / MANIFEST
    for parent in [folder, *folder.resolve().parents]:
        yield parent / MANIFEST
        yield parent / "recordings" / MANIFEST


def load_aligned(folder: str | Path, *, manifest: str | Path | None = None, split: str | None = None,
                 with_points: bool = False) -> ProgramTable:
    """One aligned recording. `split` overrides the manifest's; without either it is 'train'."""
    from feedlog.align.tables import read_table  # align is only needed to read its files

    folder = Path(folder)
    blocks_path = folder / "blocks.parquet"
    if not blocks_path.is_file():
        raise ModelError(f"{folder}: no blocks.parquet (is this a `feedlog align` output folder?)")
    try:
        blocks, meta = read_table(blocks_path)
        points = read_table(folder / "points.parquet")[0] if with_points and (folder / "points.parquet").is_file() else None
    except FeedlogError as exc:
        raise ModelError(str(exc)) from None
    name = folder.name
    entries: dict[str, ManifestEntry] = {}
    found: list[Path] = []
    candidates = [Path(manifest)] if manifest is not None else _manifest_candidates(folder, meta)
    for cand in candidates:
        if cand.is_file():
            entries = _entries(cand)
            found.append(cand)
            if name in entries:
                break
    listed = entries.get(name)
    # left out of the manifest beside its recording (or the one given): not part of that data set
    beside = {Path(meta[k]).parent / MANIFEST for k in ("recording", "recording_path") if meta.get(k)}
    unlisted = ({"unlisted_in": str(found[0])} if found and listed is None and (manifest is not None or found[0] in beside)
                else {})
    profile = None
    if listed is not None and listed.profile:
        profile = load_profile(listed.profile)
    program_text = None
    program_path = None if listed is None else listed.program_path
    if program_path is not None and program_path.is_file():
        program_text = program_path.read_text()
    if program_text is not None:
        blocks = _attach_program_columns(blocks, program_text, name, profile)
    fields = {} if listed is None else listed.fields
    return ProgramTable(
        name, blocks, program=str(fields.get("family", name)), split=split or (listed.split if listed else "train"),
        points=points, profile=profile, program_text=program_text,
        metadata={k: str(v) for k, v in fields.items()} | {
            "aligned_dir": str(folder), "recording": str(meta.get("recording", ""))} | unlisted)


def _attach_program_columns(blocks, text: str, name: str, profile):
    """The program-table columns align does not carry (G64 Q: `merge_tol_mm`), from the program."""
    from feedlog.train.features import PROGRAM_COLUMNS, with_program_columns

    if all(c in blocks.columns for c in PROGRAM_COLUMNS):
        return blocks
    try:
        from feedlog.toolpath import load_program

        program = load_program(text, name=name)
    except (ImportError, FeedlogError):
        return blocks  # models then take LinuxCNC's default Q = P (features.merge_tol_eff_mm)
    return with_program_columns(blocks, program, profile)


def is_align_dataset(path: Path) -> bool:
    """align's OUTDIR/dataset/ (the same tables as the recordings' folders, partitioned): a shell glob
    `aligned/*` passes it along with the recordings' folders."""
    from feedlog.dataset import DATASET

    return path.name == DATASET and (path / "blocks").is_dir() and not (path / "blocks.parquet").is_file()


def expand_aligned(paths: Iterable[str | Path]) -> list[Path]:
    """Aligned folders from the given paths: a folder with blocks.parquet, or a folder of such folders.
    align's dataset/ folder among several paths is skipped (it repeats their tables)."""
    paths = list(map(Path, paths))
    datasets = [p for p in paths if is_align_dataset(p)]
    if datasets and len(datasets) == len(paths):
        raise ModelError(f"{datasets[0]}: this is align's partitioned dataset; pass the folder align wrote "
                         f"({datasets[0].parent}) or its recording folders ({datasets[0].parent}/*)")
    out: list[Path] = []
    for p in paths:
        if p in datasets:
            continue
        if (p / "blocks.parquet").is_file():
            out.append(p)
        elif p.is_dir():
            found = sorted(d for d in p.iterdir() if (d / "blocks.parquet").is_file())
            if not found:
                raise ModelError(f"{p}: holds no aligned recordings (no */blocks.parquet)")
            out += found
        else:
            raise ModelError(f"{p}: not an aligned recording folder")
    return out


@dataclass(frozen=True)
class LoadTask:
    folder: str                   # absolute: a worker may run in another directory
    manifest: str | None = None
    split: str | None = None


def load_task(task: LoadTask) -> ProgramTable:
    """One aligned folder, on a worker of `feedlog.execution`."""
    return load_aligned(task.folder, manifest=task.manifest, split=task.split)


def load_many(paths: Iterable[str | Path], *, manifest: str | Path | None = None,
              test: Iterable[str] = (), runner: TaskRunner | None = None) -> list[ProgramTable]:
    """Every aligned recording under `paths`; names in `test` are held out whatever the manifest says.

    `runner` (a `feedlog.execution.TaskRunner`) reads the folders in parallel or on a cluster; the
    tables are the same as read here one by one (folders are passed as absolute paths either way).
    """
    test = set(test)
    tasks = [LoadTask(str(f.resolve()), None if manifest is None else str(Path(manifest).resolve()),
                      "test" if f.name in test else None) for f in expand_aligned(paths)]
    results = (runner or TaskRunner(jobs=1, progress=False)).run(
        load_task, tasks, desc="load", label=lambda t: Path(t.folder).name)
    bad = [r for r in results if not r.ok]
    if bad:
        raise ModelError(str(bad[0].error) + (f" (and {len(bad) - 1} more folder(s))" if len(bad) > 1 else ""))
    tables = [r.value for r in results]
    unknown = test - {t.name for t in tables}
    if unknown:
        raise ModelError(f"--test names no loaded recording: {', '.join(sorted(unknown))}")
    return tables
