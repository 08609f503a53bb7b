"""A batch of conversions: the CAM files named by files, folders and patterns, each converted into an output
folder (:func:`prs3_post.app.convert.write_conversion`) in worker processes, every file whole or absent, and
what each made or why it failed."""

from __future__ import annotations

import glob
import os
import signal
import stat
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from prs3_post.app.convert import ConvertReport, ConvertSettings, write_conversion
from prs3_post.app.workers import Died, run_tasks
from prs3_post.core.errors import STDIN_PATH, InputError, Prs3Error, shown_path
from prs3_post.core.input_files import input_size
from prs3_post.core.output_files import is_stdout, refuse_overwriting, remove_temp_files
from prs3_post.core.types import Progress
from prs3_post.kinematics.prs3.blocks import THREADS_VARIABLE
from prs3_post.machine.loading import Dialect
from prs3_post.readers.registry import suffixes


@dataclass(frozen=True, slots=True)
class FileOutcome:
    """How one file of a batch went.

    Attributes
    ----------
    input : str — as found
    output : str — the program's path (written only when ``ok``)
    ok : bool
    error : str — ``path:line: reason`` (empty when ok)
    exit_code : int — the error's (0 when ok): 2 unreadable input or output, 1 limit or reach, or its
        worker died (killed, out of memory: ``a worker died while converting FILE (signal 9)``)
    report : ConvertReport | None — None when it failed
    seconds : float — wall time of this file
    exists : bool — it failed because its program exists already (kept: see ``force``)
    keyed : str — ``error`` with the request keys it names as ``{key}``, for a front end to word
        (:class:`~prs3_post.core.errors.KeyedMessage`); empty when it names none
    keys : tuple of str — the keys ``keyed`` names (empty: any ``{key}`` in it)
    suggested_origin : (3,) str | None — mm, the part origin the error found to fit, as exact decimal
        texts (:class:`~prs3_post.check.placement.Placement`), for a front end to say how to give it
    """

    input: str
    output: str
    ok: bool
    error: str = ""
    exit_code: int = 0
    report: ConvertReport | None = None
    seconds: float = 0.0
    exists: bool = False
    keyed: str = ""
    keys: tuple[str, ...] = ()
    suggested_origin: tuple[str, str, str] | None = None

    def record(self) -> dict[str, object]:
        """JSON-ready data."""
        return {"input": shown_path(self.input), "output": self.output if self.ok else None, "ok": self.ok,
                "error": self.error or None, "seconds": round(self.seconds, 3),
                "report": None if self.report is None else self.report.record()}


@dataclass(frozen=True, slots=True)
class BatchResult:
    """Every file's outcome, in input order, and what was not converted because the batch stopped."""

    outcomes: tuple[FileOutcome, ...]
    not_started: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def failures(self) -> tuple[FileOutcome, ...]:
        """The files that failed, in input order."""
        return tuple(o for o in self.outcomes if not o.ok)

    @property
    def moves(self) -> int:
        """Motion records of the converted files: moves, arcs and drilled holes as the input states them."""
        return sum(o.report.motion_records for o in self.outcomes if o.report is not None)

    def record(self) -> dict[str, object]:
        """JSON-ready data: the files and a summary."""
        return {"files": [o.record() for o in self.outcomes], "not_started": list(self.not_started),
                "summary": {"files": len(self.outcomes) + len(self.not_started),
                            "converted": len(self.outcomes) - len(self.failures), "failed": len(self.failures),
                            "not_started": len(self.not_started), "motion_records": self.moves,
                            "seconds": round(self.seconds, 3)}}


def collect_inputs(items: Sequence[str], *, exclude: str | None = None, exclude_suffix: str = ".ngc",
                   repeats: list[tuple[str, str]] | None = None) -> list[str]:
    """The input files named by ``items``: files as given, directories searched recursively for
    CAM files (the registered formats' :func:`~prs3_post.readers.registry.suffixes`; regular files only, in name order),
    glob patterns expanded. Each file once, in the order found.

    Parameters
    ----------
    exclude : str | None — the output folder: a directory search does not descend into it; when it is
        itself a folder searched, its files ending in ``exclude_suffix`` (the programs) are left out
    repeats : list, optional — gets ``(name, first name)`` for each name of a file found already (the
        same path twice, or a symbolic link to it): converted once, and said so

    Raises
    ------
    InputError
        An item that names nothing (no such file, or a pattern or directory without CAM files).
    """
    if STDIN_PATH in items and len(items) > 1:
        raise InputError("standard input is one input: convert it alone (with -o FILE or -o -), the other files in "
                         "another command", path=STDIN_PATH)
    found: list[str] = []
    skip = os.path.realpath(exclude) if exclude is not None else None

    first: dict[str, str] = {}

    def add(path: str) -> None:
        key = os.path.realpath(path)
        if key not in first:
            first[key] = path
            found.append(path)
        elif repeats is not None:
            repeats.append((path, first[key]))

    for item in items:
        if item == STDIN_PATH:
            found.append(item)
        elif os.path.isdir(item):
            hits = list(_search(item, skip, exclude_suffix))
            if not hits:
                raise InputError("no CAM files in this directory (searched for "
                                 f"{', '.join(suffixes())})", path=item)
            for hit in hits:
                add(hit)
        elif os.path.lexists(item) or not glob.has_magic(item):
            add(item)                                  # the reader says what is wrong with it
        else:
            matches = sorted(glob.glob(item, recursive=True))
            if not matches:
                raise InputError("no file matches this pattern", path=item)
            for match in matches:
                if os.path.isdir(match):
                    for hit in _search(match, skip, exclude_suffix):
                        add(hit)
                else:
                    add(match)
    return found


def _search(folder: str, skip: str | None, skip_suffix: str) -> Iterator[str]:
    """CAM files under ``folder`` in name order: regular files only (a FIFO would block, a device never
    ends); never inside the output folder ``skip``, except when that is a folder searched itself:
    then only its files ending in ``skip_suffix`` (programs, maybe of an earlier run) are left out."""
    endings = suffixes()
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        here = os.path.realpath(root)
        if skip is not None:
            dirs[:] = [d for d in dirs if os.path.realpath(os.path.join(root, d)) != skip]
        for name in sorted(files):
            path = os.path.join(root, name)
            if not name.lower().endswith(endings):
                continue
            if here == skip and name.lower().endswith(skip_suffix.lower()):
                continue
            try:
                regular = stat.S_ISREG(os.stat(path).st_mode)
            except OSError:
                regular = True                             # unreadable: let the reader say so
            if regular:
                yield path


def output_path(input_path: str, outdir: str, dialect: Dialect) -> str:
    """``OUTDIR/<input stem><dialect extension>``."""
    return os.path.join(outdir, Path(input_path).stem + dialect.extension)


def prepare_outdir(outdir: str) -> None:
    """Create the output folder if it does not exist, and check that files can be made in it.

    Raises
    ------
    InputError
        ``the output folder's name is empty``, ``cannot create the output folder: <reason>``, ``is not a
        folder``, or ``cannot write in the output folder: permission denied`` (or ``read-only file system``).
    """
    if not outdir:
        raise InputError("the output folder's name is empty: give the folder the programs go to (e.g. -d out)",
                         path="''")
    try:
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder: {exc.strerror or exc}", path=outdir) from exc
    if not os.path.isdir(outdir):
        raise InputError("is not a folder: give the folder the programs go to", path=outdir)
    if not os.access(outdir, os.W_OK | os.X_OK):
        try:
            read_only = bool(os.statvfs(outdir).f_flag & os.ST_RDONLY)
        except OSError:
            read_only = False
        reason = "read-only file system" if read_only else "permission denied"
        raise InputError(f"cannot write in the output folder: {reason}", path=outdir)


#: What a file whose program exists already (and is kept) fails with.
EXISTS = "exists already: kept"


class OutputExists(InputError):
    """The program exists already and replacing it was not asked for."""


def convert_one(input_path: str, output: str, settings: ConvertSettings, *, force: bool = False,
                progress: Progress | None = None) -> FileOutcome:
    """Convert one file and write its program atomically; every :class:`Prs3Error` becomes a failed outcome.
    ``progress``: told the bytes read of the file's size."""
    start = time.perf_counter()
    try:
        refuse_overwriting({"its program": output}, {"being converted": input_path})
        if not force and not is_stdout(output) and os.path.lexists(output):
            raise OutputExists(f"{EXISTS} (it is replaced only when forced)", path=output)
        report = write_conversion(input_path, output, settings, progress=progress)
    except Prs3Error as error:
        from prs3_post.check.placement import Placement  # loaded by the conversion already

        message, keyed = str(error), error.carried() if error.names_keys else ""
        # an InputError starts with the file it is about; a limit or reach error found by no line (no
        # placement fits the whole file) says which input it is about first, as every failure does
        name = shown_path(input_path)
        if not isinstance(error, InputError) and not message.startswith(name):
            message, keyed = f"{name}: {message}", keyed and f"{name}: {keyed}"
        return FileOutcome(input=input_path, output=output, ok=False, error=message, exit_code=error.exit_code,
                           seconds=time.perf_counter() - start, exists=isinstance(error, OutputExists), keyed=keyed,
                           keys=() if isinstance(error.names_keys, bool) else error.names_keys,
                           suggested_origin=error.suggested_origin if isinstance(error, Placement) else None)
    return FileOutcome(input=input_path, output=output, ok=True, report=report,
                       seconds=time.perf_counter() - start)


def _worker_init(threads: int) -> None:
    """A worker: the kinematics' thread count, and Ctrl-C as in the main process (the forkserver's
    children inherit an ignored SIGINT): an interrupted write removes its temp file."""
    os.environ[THREADS_VARIABLE] = str(threads)
    signal.signal(signal.SIGINT, signal.default_int_handler)


def convert_batch(inputs: Sequence[str], outdir: str, settings: ConvertSettings, *, jobs: int = 1,
                  fail_fast: bool = False, force: bool = False,
                  on_done: Callable[[FileOutcome], None] | None = None,
                  progress: Progress | None = None) -> BatchResult:
    """Convert every input into ``outdir``, ``jobs`` files at a time in worker processes.

    Outputs are :func:`output_path`; two inputs with the same stem would write the same program, so
    both fail (neither is written: which one wins would depend on timing). An input that would be
    overwritten by its own output fails. With ``fail_fast`` the first failure stops the batch: files
    not started are listed in ``not_started``; files under way finish (each is whole or absent).
    The workers end with this process however it ends, writing nothing more; one that dies fails
    only the file it was converting (:mod:`prs3_post.app.workers`).

    Parameters
    ----------
    jobs : int — worker processes (1: in this process); each runs the kinematics on
        ``max(1, cores // jobs)`` threads, so that processes × threads ≤ cores
    on_done : called in this process with each outcome as it comes
    progress : told the bytes read of all the inputs' size, in this process: as they are read by a
        conversion in this process, a file at a time as its worker finishes it

    Returns
    -------
    BatchResult — outcomes in input order
    """
    started = time.perf_counter()
    if STDIN_PATH in inputs:
        raise InputError("standard input has no file name to name its program after: convert it alone, into one "
                         "file or standard output (-o -)", path=STDIN_PATH)
    prepare_outdir(outdir)
    outputs = [output_path(p, outdir, settings.dialect) for p in inputs]
    owners: dict[str, list[int]] = {}
    for index, out in enumerate(outputs):
        owners.setdefault(os.path.realpath(out), []).append(index)
    results: dict[int, FileOutcome] = {}
    todo: list[int] = []
    for index, out in enumerate(outputs):
        same = owners[os.path.realpath(out)]
        if len(same) > 1:
            others = ", ".join(inputs[i] for i in same if i != index)
            results[index] = FileOutcome(
                input=inputs[index], output=out, ok=False, exit_code=2,
                error=f"{inputs[index]}: has the same name as {others}: both would be written to {out} "
                      "(convert them into different folders)")
        else:
            todo.append(index)
    for index in sorted(results):
        if on_done is not None:
            on_done(results[index])
    stopped = fail_fast and bool(results)
    not_started: list[int] = []
    tally = _BytesDone(inputs, todo, progress)
    if stopped:
        not_started = todo
    elif jobs <= 1 or len(todo) <= 1:
        for position, index in enumerate(todo):
            outcome = convert_one(inputs[index], outputs[index], settings, force=force, progress=tally.reading(index))
            tally.finished(index)
            results[index] = outcome
            if on_done is not None:
                on_done(outcome)
            if fail_fast and not outcome.ok:
                not_started = todo[position + 1:]
                break
    else:
        def finished(outcome: FileOutcome) -> None:
            tally.finished(inputs.index(outcome.input))
            if on_done is not None:
                on_done(outcome)

        not_started = _run_parallel(inputs, outputs, todo, settings, jobs, fail_fast, force, results,
                                    finished if progress is not None else on_done)
    return BatchResult(outcomes=tuple(results[i] for i in sorted(results)),
                       not_started=tuple(inputs[i] for i in not_started), seconds=time.perf_counter() - started)


def convert_single(input_path: str, output: str, settings: ConvertSettings, *, force: bool = False,
                   on_done: Callable[[FileOutcome], None] | None = None,
                   progress: Progress | None = None) -> BatchResult:
    """Convert one file (``-``: standard input) into the program ``output``: a file (written atomically;
    one that exists is kept unless ``force``), or ``-``, standard output, which gets the program once it
    is complete (nothing of a file that fails). In this process; ``on_done`` and ``progress`` as in
    :func:`convert_batch`."""
    started = time.perf_counter()
    outcome = convert_one(input_path, output, settings, force=force, progress=progress)
    if on_done is not None:
        on_done(outcome)
    return BatchResult(outcomes=(outcome,), seconds=time.perf_counter() - started)


class _BytesDone:
    """A batch's progress in bytes: the files finished, and the one being read in this process."""

    def __init__(self, inputs: Sequence[str], todo: list[int], progress: Progress | None):
        self.progress = progress
        self.sizes = {index: input_size(inputs[index]) for index in todo} if progress is not None else {}
        self.total = float(sum(self.sizes.values()))
        self.done = 0.0

    def reading(self, index: int) -> Progress | None:
        """The progress of file ``index`` read in this process."""
        progress = self.progress
        if progress is None:
            return None
        size = self.sizes[index]

        def told(done: float, total: float) -> None:
            progress(self.done + (size * done / total if total > 0 else 0.0), self.total)
        return told

    def finished(self, index: int) -> None:
        if self.progress is not None:
            self.done += self.sizes.get(index, 0)
            self.progress(self.done, self.total)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def default_jobs() -> int:
    """Worker processes by default: the cores this process may run on."""
    return _cores()


def _run_parallel(inputs: Sequence[str], outputs: list[str], todo: list[int], settings: ConvertSettings, jobs: int,
                  fail_fast: bool, force: bool, results: dict[int, FileOutcome],
                  on_done: Callable[[FileOutcome], None] | None) -> list[int]:
    """Run ``todo`` in worker processes (:mod:`prs3_post.app.workers`), at most ``jobs`` files at a time;
    the indices not started. A worker that dies fails only the file it was converting."""
    threads = max(1, _cores() // jobs)
    since = time.time()

    def work(index: int) -> FileOutcome:
        return convert_one(inputs[index], outputs[index], settings, force=force)

    def done(index: int, result: FileOutcome | Died) -> bool:
        outcome = result if isinstance(result, FileOutcome) else _died(inputs[index], outputs[index], result, since)
        results[index] = outcome
        if on_done is not None:
            on_done(outcome)
        return fail_fast and not outcome.ok

    return run_tasks(work, todo, jobs, setup=lambda: _worker_init(threads), done=done)


def _died(input_path: str, output: str, death: Died, since: float) -> FileOutcome:
    """The failure of a file whose worker died (killed, out of memory): its program was not written,
    and the temp file it left (no cleanup runs in a killed process) is removed: one made since the
    batch started (``since``, :func:`time.time`) is this batch's, whose outputs are all different."""
    remove_temp_files(output, since - 1.0)              # a file's time may lag the clock by a tick
    return FileOutcome(input=input_path, output=output, ok=False, exit_code=1,
                       error=f"a worker died while converting {input_path} ({death.reason})")


def outcome_line(outcome: FileOutcome) -> str:
    """One tab-separated line per file: ``ok<TAB>INPUT<TAB>OUTPUT<TAB>N moves`` or
    ``failed<TAB>INPUT<TAB>-<TAB>path:line: reason``."""
    if outcome.ok and outcome.report is not None:
        r = outcome.report
        return (f"ok\t{shown_path(outcome.input)}\t{outcome.output}\t{r.input_moves} moves, {r.arcs} arcs, "
                f"{r.cycle_holes} holes in; {r.emitted_moves} program moves, {r.subdivisions} subdivisions; "
                f"{outcome.seconds:.3f} s")
    return f"failed\t{shown_path(outcome.input)}\t-\t{_one_line(outcome.error)}"


def _one_line(text: str) -> str:
    return " ".join(text.split())


def batch_summary(result: BatchResult) -> str:
    """The summary for people: counts, throughput, then every failure (``path:line: reason``)."""
    converted = len(result.outcomes) - len(result.failures)
    rate = result.moves / result.seconds if result.seconds > 0 else 0.0
    lines = [f"prs3-post: converted {converted} of {len(result.outcomes) + len(result.not_started)} files, "
             f"{result.moves} input moves, arcs and holes in {result.seconds:.2f} s ({rate:,.0f}/s)"]
    if result.failures:
        lines.append(f"prs3-post: {len(result.failures)} failed:")
        lines += [f"  {_one_line(o.error)}" for o in result.failures]
    if result.not_started:
        lines.append(f"prs3-post: not started (stopped at the first failure): {', '.join(result.not_started)}")
    return "\n".join(lines) + "\n"
