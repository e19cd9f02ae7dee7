"""Do two revisions give the same outputs? The README tour and the main job, file by file.

A refactoring (modules moved, code reorganised) must not change what users get. This
script runs every command of README's tour and README's main job (the batch inversion of
``data/observations/``) once with the code of a git revision ``--base`` and once with the
working tree, each in its own empty folder with its own empty numba cache (so both compile
their kernels the same way, in the command's own process), and compares every file the
commands write and everything they print, byte by byte. Two kinds of field are expected to
differ and are compared after normalising: the run's, the code's and the shared data
folders (absolute paths in summaries and in ``shapes list``) and wall or CPU times (JSON keys
and CSV columns ending in ``_s``). Everything else — magnitudes, estimates, summaries,
Parquet tables, PNG figures — must be identical.

Usage::

    python -m benchmarks.same_outputs --base main          # or any revision
    python -m benchmarks.same_outputs --base HEAD~3 --out report.json

The JSON report lists the files compared, the identical ones and every difference. The
exit status is 1 when anything differs.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._machine import machine_info
from benchmarks._report import emit_report

ROOT = Path(__file__).resolve().parents[1]
#: JSON keys of timings (``runtime_s``, ``filter_s`` …), which differ from run to run.
TIMING_KEY = re.compile(r"_s$")


def readme_commands(readme: Path) -> list[str]:
    """The tour's commands (README's "A short tour" block) and the main job's CLI part."""
    text = readme.read_text(encoding="utf-8")
    tour = text.split("## A short tour", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    commands = [line.split("  #", 1)[0].strip() for line in tour.splitlines() if line.strip()]
    main_job = text.split("<!-- main-job -->", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    commands.append(main_job.strip().split(" && ")[-1])
    return commands


def run_commands(code: Path, commands: list[str], folder: Path) -> list[dict]:
    """Run ``commands`` with the package of ``code`` in ``folder``; stdout to files."""
    folder.mkdir(parents=True)
    (folder / "data").symlink_to(ROOT / "data")
    env = dict(os.environ, PYTHONPATH=str(code), OMP_NUM_THREADS="1")
    env["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="numba-cache-")
    log = []
    for index, command in enumerate(commands):
        argv = shlex.split(command)
        assert argv[0] == "lightcurve", command
        start = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "lightcurve", *argv[1:]],
            cwd=folder,
            env=env,
            capture_output=True,
            text=True,
        )
        (folder / f"stdout_{index:02d}.txt").write_text(done.stdout)
        log.append(
            {"command": command, "status": done.returncode, "seconds": time.perf_counter() - start}
        )
        if done.returncode:
            log[-1]["stderr"] = done.stderr[-2000:]
    return log


def _normalised_json(value, folder: str):
    if isinstance(value, dict):
        return {
            key: None if TIMING_KEY.search(key) else _normalised_json(item, folder)
            for key, item in value.items()
        }
    if isinstance(value, list):
        return [_normalised_json(item, folder) for item in value]
    if isinstance(value, str):
        return value.replace(folder, "<run>")
    return value


def _normalised(path: Path, folder: Path, code: Path) -> bytes:
    data = path.read_bytes()
    if path.suffix == ".json":
        return json.dumps(_normalised_json(json.loads(data), str(folder))).encode()
    if path.suffix in {".txt", ".csv"}:
        text = data.decode("utf-8", "replace").replace(str(ROOT / "data"), "<data>")
        text = text.replace(str(code), "<code>")
        text = text.replace(str(folder), "<run>")
        if path.suffix == ".csv":
            rows = list(csv.reader(io.StringIO(text)))
            timing = {
                i for i, name in enumerate(rows[0] if rows else ()) if TIMING_KEY.search(name)
            }
            rows = [[cell for i, cell in enumerate(row) if i not in timing] for row in rows]
            return json.dumps(rows).encode()
        return text.encode()
    return data


def compare(base: Path, head: Path, base_code: Path, head_code: Path) -> dict:
    """Every file of the two run folders, compared after normalising run paths and times."""

    def files(folder: Path) -> dict[str, Path]:
        return {
            str(path.relative_to(folder)): path
            for path in folder.rglob("*")
            if path.is_file() and path.relative_to(folder).parts[0] != "data"
        }

    a, b = files(base), files(head)
    common = sorted(set(a) & set(b))
    identical = [name for name in common if a[name].read_bytes() == b[name].read_bytes()]
    equal_normalised = [
        name
        for name in common
        if name not in identical
        and _normalised(a[name], base, base_code) == _normalised(b[name], head, head_code)
    ]
    return {
        "files": len(common),
        "identical_bytes": len(identical),
        "identical_after_normalising_paths_and_times": equal_normalised,
        "different": [n for n in common if n not in identical and n not in equal_normalised],
        "only_in_base": sorted(set(a) - set(b)),
        "only_in_working_tree": sorted(set(b) - set(a)),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="git revision to compare against")
    parser.add_argument("--out", help="also write the JSON report here")
    args = parser.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="same-outputs-"))
    base_code = work / "base-code"
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(base_code), args.base],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    try:
        commands = readme_commands(ROOT / "README.md")
        runs = {
            "base": run_commands(base_code, commands, work / "base"),
            "working_tree": run_commands(ROOT, commands, work / "head"),
        }
        report = {
            "machine": machine_info(),
            "base": args.base,
            "commands": commands,
            "runs": runs,
            "comparison": compare(work / "base", work / "head", base_code, ROOT),
        }
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base_code)], cwd=ROOT)
    emit_report(report, args.out)
    comparison = report["comparison"]
    failed = any(run["status"] for log in runs.values() for run in log)
    return int(
        failed
        or bool(comparison["different"])
        or bool(comparison["only_in_base"] or comparison["only_in_working_tree"])
    )


if __name__ == "__main__":
    raise SystemExit(main())
