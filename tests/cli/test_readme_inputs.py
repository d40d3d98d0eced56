"""README.md "Bring your own data", run as written so it cannot rot.

The commands are read from the section's ``sh`` block. The files they name are made
here (logger CSVs, a candump log with its DBC and signal map); ``../shared/`` is the
shared data directory next to the project (the command is skipped where it is absent).
Each command runs as ``python -m gyrotherm`` in a fresh interpreter.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gyrotherm.codecs import read_run
from userdatakit import bus_log, logger_csv

ROOT = Path(__file__).resolve().parents[2]
SHARED = [p for p in (ROOT.parent / "shared", Path("/work/shared")) if p.is_dir()]
STEP_TIMEOUT_S = 300.0  # generous bound per command on loaded cores; not a speed check


def section_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Bring your own data\n", 1)[1].split("\n## ", 1)[0]
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        for line in block.splitlines():
            command = re.sub(r"(^|\s+)#.*$", "", line).strip()
            if command:
                commands.append(command)
    return commands


def test_readme_bring_your_own_data(tmp_path: Path) -> None:
    for i, top in enumerate((45.0, 60.0, 52.0), start=1):
        logger_csv(tmp_path / f"logger-{i}.csv", top_c=top, seed=i, rows=600)
    log, dbc, signals = bus_log(tmp_path / "bus", 55.0)
    shutil.copy(log, tmp_path / "bus.log")
    shutil.copy(dbc, tmp_path / "my-gyro.dbc")
    shutil.copy(signals, tmp_path / "my-gyro.toml")
    commands = section_commands()
    assert len(commands) == 6
    ran = []
    for command in commands:
        argv = shlex.split(command)
        assert argv[0] == "gyrotherm"
        if any(a.startswith("../shared/") for a in argv):
            if not SHARED:
                continue
            argv = [str(SHARED[0] / a.removeprefix("../shared/"))
                    if a.startswith("../shared/") else a for a in argv]
        proc = subprocess.run([sys.executable, "-m", "gyrotherm", "-q", *argv[1:]],
                              cwd=tmp_path, capture_output=True, text=True,
                              timeout=STEP_TIMEOUT_S, check=False)
        assert proc.returncode == 0, f"{command}\n{proc.stderr}"
        ran.append(argv[1])
    assert ran.count("fit") >= 2 and "evaluate" in ran and "import" in ran
    for cal in ("logger.cal.json", "bus.cal.json"):
        assert json.loads((tmp_path / cal).read_text())["model"]["name"] == "t2"
    imported = read_run(tmp_path / "imported" / "logger-2.csv")
    assert imported.metadata["source_file"] == "logger-2.csv"
    assert imported.metadata["unit_x"] == "rad/s"
    if SHARED:
        doc = json.loads((tmp_path / "bmi270.cal.json").read_text())
        assert [r["name"] for r in doc["provenance"]["runs"]] == [
            "bmi270_static_clean:cold", "bmi270_static_clean:hot"]
        # the PuTTY captures: the curator's row counts (SOURCE.md), the dropped lines listed
        cold = read_run(tmp_path / "putty" / "BMI_270_cold_test_.csv")
        hot = read_run(tmp_path / "putty" / "BMI_270_hot_test.csv")
        assert (len(cold), len(hot)) == (3255, 6533)
        assert hot.metadata["dropped_lines"].startswith("3: line 2: expected 7 fields")
        assert cold.time_s[-1] == pytest.approx(3254 * 0.02, abs=1e-9)


@pytest.mark.parametrize("command", section_commands())
def test_readme_commands_parse(command: str) -> None:
    """Each command is accepted by the parser (options exist, files come first)."""
    from gyrotherm.cli import build_parser

    args = build_parser().parse_args(shlex.split(command)[1:])
    assert args.runs
