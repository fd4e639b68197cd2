"""Every command example of the README, of docs/ and of `--help` runs as printed (issue 30).

The examples are taken from the texts themselves, so that a new example is run without
anyone listing it:

- README.md: every ```bash block (run as one script, with `bash -e`); every ```python block
  (run by this Python, after an `import pymr`: the README's blocks read as one session);
  every line of a plain
  ``` block that starts with `pymr ` or `mrsim ` (or `$ ` before them), backslash
  continuations joined; every inline `pymr ...` / `mrsim ...`; every inline `--set`
  example (`GROUP.ITEM=VALUE`), run on the README's own single-rate tank scene,
  input/tank_gun_turret.nml, the scene the README's first run and summary are of.
- `pymr --help`, `pymr COMMAND --help` for every command, and `mrsim --help`: each "e.g."
  that gives a command or a `GROUP.ITEM=VALUE` (run on the same tank scene).

Not examples: the usage synopses, whose placeholders (SCENE.nml, NAME, [--set ...],
caseNNNN) tests/test_cli_docs.py checks against the parsers; an inline command's bare name
(`pymr run` in a sentence); and the spans in MENTIONS, which name an option in prose.

Each example runs in its own temporary folder holding a copy of input/ (and an empty
docs/), with exit status 0 expected. What the test does beyond the printed text is in the
tables below, each entry with its reason: lines not run (NOT_RUN), what an example needs
done before it (SETUP: the files an earlier example or a cluster would leave), and options
appended to a few slow commands (ADJUST: fewer repeats, frames or cases; the same code).
A table entry that no longer matches an example fails the test, so the tables stay honest.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from pymr.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: The texts whose examples run: the README, then each file of docs/ (the user's guide).
TEXTS = [README] + sorted((ROOT / "docs").glob("*.md"))
#: The README's single-rate tank scene: the --set examples are run on it.
TANK = "input/tank_gun_turret.nml"

#: Lines of the README's bash blocks that the test does not run, and why.
NOT_RUN = {
    "bash .ci/setup && ": "prefix: installs the machine's packages and pymr (apt-get, pip); the suite runs on an "
                          "installed pymr, the rest of the line is run",
    "pytest": "the test suite itself",
    "pip install meson-python meson ninja numpy scipy pytest": "installs packages from PyPI",
    "pip install --no-build-isolation -e .    # editable: importing pymr rebuilds the kernel":
        "installs pymr into the environment under test",
    "pytest                                    # not \"python -m pytest\": that imports the source folder":
        "the test suite itself",
}

#: Inline spans that name a command's option in a sentence; they are not commands to run.
MENTIONS = {
    "pymr scene --absolute-paths": "names the option that `pymr scene SCENE` takes",
    "mrsim --progress": "names the option that `mrsim SCENE` takes",
}

#: Options appended to slow examples (the same commands, the same code paths), and why.
ADJUST = {
    "pymr animate tank_gun_turret.csv --exaggerate 50": (["--frames", "20"], "200 frames take 20 s"),
    "pymr bench rhs": (["--repeats", "1"], "timing repeats; the work is the same"),
    "pymr bench lapack": (["--repeats", "1"], "timing repeats; the work is the same"),
    "pymr bench effects": (["--repeats", "1"], "timing repeats; the work is the same"),
    "pymr bench chain": (["--repeats", "1"], "timing repeats (30 s with the default 7)"),
    "pymr bench spacecraft": (["--repeats", "1"], "timing repeats (30 s with the default 5)"),
    "pymr bench output": (["--repeats", "1"], "timing repeats (23 s with the default 5)"),
    "pymr bench auto": (["--repeats", "1"], "timing repeats (40 s with the default 5)"),
    "pymr bench table1": (["--repeats", "5"], "timing repeats (table1 takes at least 5; 21 by default)"),
    "pymr bench modal-import": (["--sizes", "2000"], "the 300k-DOF models take minutes (hours with reference BLAS); "
                                                      "the same code at one small size"),
    "pymr study input/tank_gun_turret.nml --marker muzzle -o docs/tank_study":
        (["--quick", "--repeats", "1"], "the full study takes 7 min; --quick runs every family with fewer settings"),
    "pymr study input/hard/stiff_barrel.nml --marker muzzle -o docs/stiff_barrel_study":
        (["--quick", "--repeats", "1"], "the full study takes longer still"),
    "pymr study input/tank_on_the_move.nml --marker muzzle --repeats 3":
        (["--quick", "--repeats", "1"], "the full study takes 6 min"),
}

def adjusted(script: str, extra: list[str]) -> str:
    """`script` with ADJUST's options: an option it gives already takes the new value in its
    place (pymr refuses an option of one value given twice), the others are appended."""
    words, added, i = script.split(" "), [], 0
    while i < len(extra):
        option, value = extra[i], extra[i + 1] if i + 1 < len(extra) and not extra[i + 1].startswith("--") else None
        if value is not None and option in words:
            words[words.index(option) + 1] = value
        else:
            added += [option] + ([value] if value is not None else [])
        i += 1 if value is None else 2
    return " ".join(words + added)


#: Scene copies run over a shorter time for the studies of ADJUST (a study has no --set).
SHORTER = {
    "pymr study input/tank_gun_turret.nml --marker muzzle -o docs/tank_study": ("input/tank_gun_turret.nml", 0.1),
    "pymr study input/hard/stiff_barrel.nml --marker muzzle -o docs/stiff_barrel_study":
        ("input/hard/stiff_barrel.nml", 0.02),
    "pymr study input/tank_on_the_move.nml --marker muzzle --repeats 3": ("input/tank_on_the_move.nml", 0.3),
}


def _fe_barrel(work: Path) -> None:
    """The files `pymr modal-import --mass M.mtx --stiffness K.mtx --nodes nodes.csv
    --interface 1 21` reads, as a finite-element code would export them: the tank's barrel
    as 20 beam elements, 21 nodes of 6 DOFs."""
    sys.path.insert(0, str(Path(__file__).parent))
    from test_modal_import import AREA, E, I2, L, RHO, beam_matrices, write_fe
    k, m, nodes = beam_matrices(L, E, RHO, AREA, I2, I2, 20)
    mp, kp, _ = write_fe(work, k, m, nodes)
    mp.rename(work / "M.mtx")
    kp.rename(work / "K.mtx")


def _checkout_tests(work: Path, *files: str) -> None:
    """The checkout's tests/ files a development command reads, copied into the work folder."""
    for f in files:
        (work / "tests" / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / "tests" / f, work / "tests" / f)


def _slurm_tasks(work: Path, folder: str) -> None:
    """What `cd runs && sbatch sweep.slurm` does on a cluster: every task of the job array,
    here one after another."""
    script = work / folder / "sweep.slurm"
    tasks = re.search(r"#SBATCH --array=0-(\d+)", script.read_text()).group(1)
    for i in range(int(tasks) + 1):
        env = {**os.environ, "SLURM_ARRAY_TASK_ID": str(i), "SLURM_SUBMIT_DIR": str(work / folder)}
        r = subprocess.run(["bash", str(script)], cwd=work, env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr


#: What an example needs done first, and why (a callable of the work folder, or the
#: earlier example whose files it reads).
SETUP = {
    # the README's first scene: the plot overlays the run printed just before
    'pymr run input/pendulum.nml --set "joint[pivot].q0=0.5" -o pendulum_half.csv': ["pymr run input/pendulum.nml"],
    "pymr animate tank_gun_turret.csv --exaggerate 50": ["pymr run input/tank_gun_turret.nml"],
    "pymr export tank_gun_turret.csv --vtk tank_vtk": ["pymr run input/tank_gun_turret.nml"],
    "pymr view tank_view.csv --exaggerate 50 --column muzzle.y gun.a1 gun.a2 energy.drive_work":
        ["pymr run input/tank_gun_turret.nml -o tank_view.csv --set "
         "\"output.quantities='coordinates','markers','energy'\""],
    "pymr animate tank_gun_turret.csv -o docs/tank_animation_3d.png --at 0.68": ["pymr run input/tank_gun_turret.nml"],
    "pymr sweep input/tank_sweep.toml --collect runs/": ["pymr sweep input/tank_sweep.toml --emit-slurm runs/",
                                                         lambda work: _slurm_tasks(work, "runs")],
    "pymr modal-import --mass M.mtx --stiffness K.mtx --nodes nodes.csv --dofs-per-node 6 --interface 1 21 "
    "--modes 20 --keep 4 -o gun.modal": [_fe_barrel],
    # docs/development.md's command prints the schema table through the checkout's tests/test_scene.py
    "python -P -c \"import sys; sys.path.insert(0, 'tests'); import test_scene; "
    "print(test_scene.schema_markdown(), end='')\"": [lambda work: _checkout_tests(work, "test_scene.py",
                                                                                "data/input_results.json")],
}


@dataclass(frozen=True)
class Example:
    where: str          # "README.md:1034" or "pymr run --help"
    script: str         # what bash runs (as printed, one command or a whole block), or Python
    lang: str = "bash"

    @property
    def id(self) -> str:
        first = self.script.strip().splitlines()[0]
        return f"{self.where}: {first[:70]}"


SET_ITEM = re.compile(r"[a-z_]+(\[[^\]\s]+\])?\.[a-z_0-9]+=\S+")
PLACEHOLDER = re.compile(r"[A-Z]{2,}|\.\.\.|[\[\]|]")


def _words(text: str) -> str:
    return " ".join(text.split())


def _set_example(item: str) -> str:
    return f"pymr run {TANK} --set {shlex.quote(item)} -o example.csv -q"


def _is_bare(command: str) -> bool:
    """`pymr run` or `mrsim` in a sentence: a program, or a program and a command, alone."""
    words = command.split()
    return len(words) == 1 or (words[0] == "pymr" and len(words) == 2 and not words[1].startswith("-"))


def _synopsis_commands(line: str) -> list[str]:
    """The commands of a usage line without placeholders ('pymr bench rhs   cost of ...';
    'mrsim --version, pymr --version   the version'); none when it has placeholders."""
    head = re.split(r"\s{2,}", line.strip())[0]
    out = []
    for part in head.split(", "):
        part = re.sub(r"\s*\[[^\]]*\]", "", part).strip()        # optional parts left out
        if part and not PLACEHOLDER.search(part) and not _is_bare(part):
            out.append(part)
    return out


def readme_examples() -> list[Example]:
    """The examples of every text of TEXTS."""
    return [ex for path in TEXTS for ex in text_examples(path)]


def text_examples(path: Path) -> list[Example]:
    name = str(path.relative_to(ROOT))
    text = path.read_text()
    lines = text.splitlines()
    examples: list[Example] = []
    fenced = [False] * len(lines)
    i = 0
    while i < len(lines):
        m = re.match(r"```(\w*)\s*$", lines[i])
        if not m:
            i += 1
            continue
        lang, start = m.group(1), i + 1
        end = next(j for j in range(start, len(lines)) if lines[j].startswith("```"))
        for j in range(i, end + 1):
            fenced[j] = True
        body = lines[start:end]
        if lang == "bash":
            kept = []
            for line in body:
                for prefix in [p for p in NOT_RUN if p.endswith(" ")]:
                    line = line.removeprefix(prefix)
                if line.strip() and line not in NOT_RUN:
                    kept.append(line)
            if kept:
                examples.append(Example(f"{name}:{start + 1}", "\n".join(kept)))
        elif lang == "python":
            examples.append(Example(f"{name}:{start + 1}", "\n".join(body), "python"))
        elif lang == "":
            joined: list[tuple[int, str]] = []
            for k, line in enumerate(body):
                if joined and joined[-1][1].endswith("\\"):
                    joined[-1] = (joined[-1][0], joined[-1][1][:-1].rstrip() + " " + line.strip())
                else:
                    joined.append((start + k + 1, line))
            for number, line in joined:
                command = line.removeprefix("$ ")
                if not re.match(r"(pymr|mrsim) ", command):
                    continue
                usage = re.search(r"\s{2,}\S", command.strip()) or PLACEHOLDER.search(command)
                commands = _synopsis_commands(command) if usage else [_words(command)]
                examples += [Example(f"{name}:{number}", c) for c in commands]
        i = end + 1
    # inline code spans outside the fenced blocks (a span may run over a line break)
    prose = "\n".join("" if f else line for line, f in zip(lines, fenced))
    for m in re.finditer(r"`([^`]+)`", prose):
        span, number = _words(m.group(1)), prose.count("\n", 0, m.start()) + 1
        item = span.removeprefix("--set ")
        if SET_ITEM.fullmatch(item):
            examples.append(Example(f"{name}:{number}", _set_example(item)))
        elif re.match(r"(pymr|mrsim)( |$)", span) and not PLACEHOLDER.search(span) and not _is_bare(span) \
                and span not in MENTIONS:
            examples.append(Example(f"{name}:{number}", span))
    return examples


def _help_texts() -> dict[str, str]:
    parser = build_parser()
    texts = {"pymr --help": parser.format_help()}
    action = next(a for a in parser._actions if a.dest == "command")
    for name, sub in action.choices.items():
        texts[f"pymr {name} --help"] = sub.format_help()
    return texts


def help_examples(mrsim_help: str) -> list[Example]:
    """Each 'e.g.' of the help texts that gives a command or a GROUP.ITEM=VALUE."""
    examples = []
    for where, text in {**_help_texts(), "mrsim --help": mrsim_help}.items():
        for m in re.finditer(r"e\.g\. ([^;()]*)", _words(text)):
            for part in re.split(r",? or |, ", m.group(1)):
                part = part.strip().rstrip(".")
                if SET_ITEM.fullmatch(part):
                    examples.append(Example(where, _set_example(part)))
                elif re.match(r"(pymr|mrsim) ", part):
                    examples.append(Example(where, part))
    return examples


def _mrsim_help() -> str:
    from pymr._locate import mrsim_path
    exe = mrsim_path() or "mrsim"
    return subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=30).stdout


def all_examples() -> list[Example]:
    """The README's examples, then --help's; a command printed twice is run once."""
    seen, out = set(), []
    for ex in readme_examples() + help_examples(_mrsim_help()):
        if ex.script not in seen:
            seen.add(ex.script)
            out.append(ex)
    return out


EXAMPLES = all_examples()


def _shell(script: str, work: Path, env: dict, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=work, env=env, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.fixture
def work(tmp_path, mrsim) -> tuple[Path, dict]:
    """A folder with a copy of input/ and an empty docs/, and the environment: this
    installation's mrsim and pymr first on PATH, no PYTHONPATH (outside the checkout, the
    installed pymr is imported)."""
    shutil.copytree(ROOT / "input", tmp_path / "input")
    (tmp_path / "docs").mkdir()
    path = os.pathsep.join([str(Path(mrsim).parent), str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return tmp_path, {**os.environ, "PATH": path, "PYTHONPATH": ""}


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_example_runs_as_printed(example, work):
    folder, env = work
    script = example.script
    for step in SETUP.get(script) or SETUP.get(script.splitlines()[0], []):
        if callable(step):
            step(folder)
        else:
            r = _shell(step, folder, env)
            assert r.returncode == 0, f"setup {step!r}: exit {r.returncode}\n{r.stderr[-2000:]}"
    if script in SHORTER:
        scene, t_end = SHORTER[script]
        text = (folder / scene).read_text()
        (folder / scene).write_text(re.sub(r"(?m)^(\s*t_end\s*=\s*)\S+", rf"\g<1>{t_end}", text, count=1))
    if script in ADJUST:
        script = adjusted(script, ADJUST[script][0])
    if example.lang == "python":
        r = subprocess.run([sys.executable, "-c", "import pymr\n" + script], cwd=folder, env=env, capture_output=True,
                           text=True, timeout=300, stdin=subprocess.DEVNULL)
    else:
        r = _shell(script, folder, env)
    assert r.returncode == 0, (f"{example.where}: {script!r}: exit {r.returncode}\n"
                               f"stderr: {r.stderr[-2000:]}\nstdout: {r.stdout[-1000:]}")
    assert "Traceback" not in r.stderr, r.stderr


def test_the_examples_are_found():
    """The extraction finds what the README and --help hold: the bash blocks, the summary's
    run, the synopsis' benches, the --set examples of both texts and the inline commands."""
    scripts = [e.script for e in EXAMPLES]
    assert any(s.startswith("pymr run input/tank_gun_turret.nml -o single.csv -q\nfor k in") for s in scripts)
    assert any(s.startswith("mrsim input/hard/tank_long.nml --set output.checkpoint_dt=10") for s in scripts)
    assert [(e.where.split(":")[0], e.script.splitlines()[1]) for e in EXAMPLES if e.lang == "python"] == [
        ("README.md", 'res = pymr.run("input/pendulum.nml")             # runs in a temporary folder, leaves no files'),
        ("docs/results.md", 'pymr.run("input/tank_gun_turret.nml", "tank.h5", overrides={"output.format": "hdf5"})'),
        ("docs/results.md", 'pymr.run("input/tank_gun_turret.nml", "tank.csv",     # writes tank.csv and tank.json'),
        ("docs/results.md", 'res = pymr.run("input/tank_gun_turret.nml", "tank.csv", overrides={'),
        ("docs/scenes.md", 'scene = pymr.Scene("input/tank_gun_turret.nml")'),
        ("docs/scenes.md", 'scene.add("scene", title="pendulum", t_end=10.0, gravity=[0.0, -9.81, 0.0])')]
    for command in ("pymr run input/tank_gun_turret.nml", "pymr scene --schema", "pymr bench table1", "mrsim --version",
                    "pymr modal-file input/tank_gun_turret.nml gun -o gun.modal",
                    "pymr sweep input/tank_sweep.toml --collect runs/", _set_example("integrator.h_slow=5e-4"),
                    _set_example("joint[elevation].q0=0.1"), _set_example("effects.joint_drives=.false.")):
        assert command in scripts, command
    from_help = [e for e in help_examples(_mrsim_help()) if e.where == "pymr run --help"]
    assert len(from_help) >= 2 and all("--set" in e.script for e in from_help)
    assert all(e.script in scripts for e in from_help)
    assert not any("SCENE" in s or "NNNN" in s or s in ("pymr run", "mrsim") for s in scripts)


def test_the_tables_name_examples_that_exist():
    """Every entry of NOT_RUN, MENTIONS, ADJUST, SHORTER and SETUP is still in the texts:
    an entry left behind by a changed example would hide nothing, but says something false."""
    text = "\n".join(t.read_text() for t in TEXTS)
    for line in NOT_RUN:
        assert line in text, f"NOT_RUN: {line!r} is not in the README or docs/"
    for span in MENTIONS:
        assert f"`{span}`" in text, f"MENTIONS: {span!r} is not in the README or docs/"
    scripts = {e.script for e in EXAMPLES} | {e.script.splitlines()[0] for e in EXAMPLES}
    for table in (ADJUST, SHORTER, SETUP):
        for command in table:
            assert command in scripts, f"{command!r} is not an example any more"
