"""Every output a command writes goes through one rule (pymr.outputs.check_output, issue 30):
an output path that is a folder (`-o .` wrote a hidden `./.png` with exit 0, or gave a
traceback), in a folder that is not there, empty, a FIFO, or one of the command's inputs is
refused before any work: one line naming the path, exit 1, nothing printed on stdout,
nothing written, the inputs unchanged.

The commands and their output options are read from pymr's own parser, so a new command or
a new output option is tried here as soon as it exists (and fails until BASE says how to
call it)."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

import pymr
from pymr.cli import build_parser, main
from pymr.outputs import check_output

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).parent))

SCENE = """\
&scene title = 'pendulum', t_end = 0.05, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'bob', kind = 'rigid', mass = 1.0, inertia = 1e-3, 1e-3, 1e-3, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob', q0 = 0.5 /
&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /
"""

#: The options that name a file a command writes.
FILE_OPTIONS = ("-o", "--json")

#: How to call each command but for its output option (files made by the `inputs`
#: fixture), and the input an output must not overwrite (None: the command reads none that
#: an output name could meet).
BASE = {
    "run": (["base.nml", "-q"], "base.nml"),
    "modal-file": (["tank.nml", "gun", "-q"], "tank.nml"),
    "modal-import": (["--mass", "m.mtx", "--stiffness", "k.mtx", "--nodes", "nodes.csv", "--interface", "1", "-q"],
                     "m.mtx"),
    "modes": (["base.nml"], "base.nml"),
    "animate": (["out.csv"], "out.csv"),
    "study": (["base.nml", "--quick", "--repeats", "1"], None),     # -o is a prefix of .csv, .png, _history.csv
    "plot": (["out.csv", "-q"], "out.csv"),
    "view": (["out.csv"], "out.csv"),
    "bench": (["rhs", "--repeats", "1"], None),
}

#: Bad output paths, each refused by every command (the input is added per command).
BAD = {
    "dot": ".",
    "dotdot": "..",
    "folder": "sub",
    "folder_slash": "sub/",
    "missing_folder": "missing/out.x",
    "file_as_folder": "base.nml/out.x",
    "empty": "",
    "fifo": "fifo",
    # standard output in many tools: pymr bench --json - wrote a file named '-' (exit 0)
    "stdout": "-",
}


def file_outputs() -> list[tuple[str, str]]:
    """(command, option) for every option of every command that names a file it writes."""
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    out = []
    for name, sub in action.choices.items():
        for a in sub._actions:
            if set(a.option_strings) & set(FILE_OPTIONS):
                out.append((name, a.option_strings[0]))
    return out


def cases():
    for command, option in file_outputs():
        for label, path in BAD.items():
            yield pytest.param(command, option, path, id=f"{command}-{option}-{label}")
        if command not in BASE or BASE[command][1] is not None:     # a command that reads an input
            yield pytest.param(command, option, None, id=f"{command}-{option}-an_input")


@pytest.fixture
def inputs(tmp_path, monkeypatch):
    """A work folder with a scene, its results (CSV and JSON), the tank, a small FE model,
    a folder and a FIFO."""
    from test_modal_import import beam_matrices, write_fe
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(SCENE)
    pymr.run("base.nml", "out.csv")
    (tmp_path / "tank.nml").write_text((ROOT / "input" / "tank_gun_turret.nml").read_text())
    k, m, nodes = beam_matrices(5.3, 2.07e11, 7850.0, 0.02, 1e-5, 1e-5, 4)
    write_fe(tmp_path, k, m, nodes)
    (tmp_path / "sub").mkdir()
    os.mkfifo(tmp_path / "fifo")
    return tmp_path


def snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in folder.rglob("*") if not p.is_fifo()}


@pytest.mark.parametrize("command, option, path", list(cases()))
def test_a_bad_output_path_is_refused_before_any_work(inputs, capfd, command, option, path):
    assert command in BASE, f"pymr {command} writes {option}: add how to call it to BASE"
    args, source = BASE[command]
    if path is None:
        path = source
    capfd.readouterr()
    before = snapshot(inputs)
    status = main([command, *args, option, path])
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert status == 1, f"exit {status}; stderr: {err[-1500:]}"
    assert len(lines) == 1 and lines[0].startswith("pymr: error: "), err
    assert (path or option) in lines[0], lines[0]
    assert out == "", f"work was done before the output was refused:\n{out[-1000:]}"
    assert snapshot(inputs) == before, "files were written or changed"
    assert (inputs / "fifo").is_fifo()


@pytest.mark.parametrize("path, message", [
    (".", r"^-o \.: is a folder, not a file: give a file name for the figure, such as \./out\.png$"),
    ("sub/", r"^-o sub/: is a folder, not a file"),
    (".png", r"^-o \.png: a suffix with no name before it \(a hidden file\)"),
    ("fig", r"^-o fig: no suffix to say the figure's format \(one of \.png, "),
    ("fig.csv", r"^-o fig\.csv: \.csv is not a format of the figure \(one of \.png, "),
    ("missing/fig.png", r"^-o missing/fig\.png: the folder missing is not there"),
    ("out.json", r"^-o out\.json: .*"),
])
def test_plot_messages(inputs, capfd, path, message):
    """The figure's path, in pymr's words (`-o .` wrote a hidden ./.png with exit 0; `-o fig`
    wrote fig.png while saying 'wrote fig')."""
    assert main(["plot", "out.csv", "-o", path]) == 1
    import re
    assert re.search(message, capfd.readouterr().err.strip().removeprefix("pymr: error: "))
    assert not list(inputs.glob("*.png")) and not (inputs / ".png").exists()


def test_the_python_functions_take_the_same_rule(inputs):
    """plot_results and animate check their output argument the same way (a PymrError
    naming it), before drawing anything."""
    from pymr.animate import animate
    from pymr.plot import plot_results
    for call in (lambda: plot_results(["out.csv"], "."), lambda: animate("out.csv", "sub"),
                 lambda: plot_results(["out.csv"], "out.csv"), lambda: animate("out.csv", "base.nml")):
        with pytest.raises(pymr.PymrError, match=r"^output (\.|sub|out\.csv|base\.nml): ") as info:
            call()
        assert "\n" not in str(info.value)
    assert sorted(p.name for p in inputs.iterdir()) == sorted(["base.nml", "out.csv", "out.json", "tank.nml", "k.mtx",
                                                              "m.mtx", "nodes.csv", "sub", "fifo"])


def test_check_output_accepts_a_good_path_and_names_the_scene_s_inputs(inputs):
    assert check_output("sub/new.png", "figure", suffixes=[".png"]) == Path("sub/new.png")
    assert check_output(inputs / "out2.csv", "results", scene="base.nml") == inputs / "out2.csv"
    with pytest.raises(pymr.OutputError, match=r"^-o base\.nml: would overwrite the scene"):
        check_output("base.nml", "results", scene="base.nml")
    with pytest.raises(pymr.OutputError, match=r"^--json: a file name expected for the figures, got 5$"):
        check_output(5, "figures", option="--json")


def test_the_default_outputs_take_the_rule_too(inputs, capfd):
    """A default output (plot: STEM.png here; animate: the CSV's .gif) that is a folder is
    refused naming it as the default."""
    (inputs / "out.png").mkdir()
    (inputs / "out.gif").mkdir()
    assert main(["plot", "out.csv"]) == 1
    assert "the default figure (-o to choose) out.png: is a folder" in capfd.readouterr().err
    assert main(["animate", "out.csv"]) == 1
    assert "the default animation (-o to choose) out.gif: is a folder" in capfd.readouterr().err


def test_sweep_output_folders(inputs, capfd):
    """A sweep's folders: --emit-slurm onto a file, and --collect where summary.csv is a
    folder, are one line and exit 1 before any case or reference runs."""
    (inputs / "s.toml").write_text('scene = "base.nml"\nmetric = "deviation:tip"\n[grid]\n"joint[pivot].q0" = [0.5]\n')
    assert main(["sweep", "s.toml", "--emit-slurm", "base.nml"]) == 1
    assert "base.nml: cannot make the --emit-slurm folder" in capfd.readouterr().err
    assert main(["sweep", "s.toml", "--emit-slurm", "runs"]) == 0
    (inputs / "runs" / "summary.csv").mkdir()
    capfd.readouterr()
    assert main(["sweep", "s.toml", "--collect", "runs"]) == 1
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "--collect runs/summary.csv: is a folder, not a file" in err, err
    assert not list((inputs / "runs").glob("reference*.csv"))
