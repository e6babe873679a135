"""Every option of every ``treeform`` command with wrong-type and out-of-range values (issue 16 item 4).

:func:`cases` walks the command tree (so a new option is swept the day it is added) and gives,
for each option, values a user may mistype: a word where a number goes, negative, zero, huge,
``nan`` and ``inf`` numbers, an unknown name, an output path that cannot be written and an
input that does not exist. :data:`VALID` lists the few of those values that an option accepts
by design (a seed of 0, ``--workers 0`` for "no cluster" ...), each with its reason.

Run as a script (``python option_sweep.py FIXTURES.json CASES.json RESULTS.json``), it runs the
cases one after the other in this one process (the command's ``main`` with the case's
arguments; stdout and stderr captured), each with its own empty output folder and a time
limit, and writes what each did: the exit code, stderr, the files left in its folder and the
seconds it took. The test (test_option_sweep.py) asserts that each ended with one ``error:``
line, a non-zero exit and nothing written.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

WRONG = {
    int: ("abc", "-5", "0", "1000000000000"),  # for --seed: 2**32 is the first too large
    float: ("abc", "-1", "0", "nan", "inf", "1e12"),
    "choice": ("nope",),
    str: ("nope",),
    "out": ("{unwritable}",),
    "in": ("{missing}",),
}

# (command, option) -> {value: why it is accepted}. Everything else in WRONG must be refused.
VALID = {
    ("*", "--seed", "0"): "seed 0 is the default",
    ("grow", "--leaves", "0"): "a bare tree (winter)",
    ("reconstruct", "--leaves", "0"): "a bare tree (winter)",
    ("batch", "--workers", "0"): "0 = one photo after the other in this process (documented)",
    ("eval", "--workers", "0"): "0 = one case after the other in this process (documented)",
    ("train seg", "--workers", "0"): "0 = scenes composed in the training process (documented)",
    ("train seg", "--noise", "0"): "no noise scenes",
    ("train seg", "--photo-trees", "0"): "no photo trees",
    ("train seg", "--fine-stride", "0"): "0 = off",
    ("train seg", "--refine", "0"): "0 = no refinement layer",
    ("train seg", "--bushes", "0"): "no bushes",
    ("train seg", "--sparse-boost", "0"): "no boost",
    ("train seg", "--tree-dice", "0"): "no dice term",
    ("train feet", "--workers", "0"): "0 = scenes composed in the training process (documented)",
    ("train feet", "--render-fraction", "0"): "no synthetic renders",
    ("train feet", "--max-minutes", "0"): "0 = no time limit (documented)",
    ("train feet", "--behind", "0"): "no tree stands nearly behind another",
    ("impostor", "--opacity", "0"): "0 = no opacity grid: the RDM's solid relief (documented)",
    ("dataset generate", "--photo-fraction", "0"): "no photo backgrounds",
    ("dataset generate", "--bare", "0"): "no leafless samples (the default)",
    ("animate", "--wind", "0"): "still air: a still, looping animation",
    ("animate", "--direction", "-1"): "an angle: any real number, taken modulo 360",
    ("animate", "--direction", "0"): "an angle",
    ("animate", "--direction", "1e12"): "an angle, taken modulo 360",
    ("reconstruct", "--rdm-rotations", "0"): "0 = no extra rotations",
    ("reconstruct", "--clumps", "0"): "0 = leaves spread evenly, no clumps (documented)",
    ("eval", "--viewer", "0"): "no case in the 3D viewer",
    ("forest", "--switch-distance", "0"): "every tree a relief impostor",
    ("forest", "--switch-distance", "1e12"): "every tree a billboard cloud",
    ("forest", "--card-px", "0"): "0 = no card tier (documented)",
    ("forest", "--card-px", "1e12"): "every far tree an impostor card",
}


# path options that name something the command writes (the others are read)
OUTPUTS = {"out", "sheet", "overlay", "plot", "cache", ("segment", "--mask"), ("segment", "--wood"),
           ("cloud", "--views")}


def _kind(param, command: str = "") -> object:
    """What WRONG values fit ``param``: int, float, 'choice', str, 'out', 'in' (or None: not swept)."""
    import enum
    import types
    import typing
    from pathlib import Path as P

    ann = param.type_descriptor.annotation
    if typing.get_origin(ann) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(ann) if a is not type(None)]
        ann = args[0] if len(args) == 1 else ann
    if isinstance(ann, type) and issubclass(ann, enum.Enum):
        return "choice"
    if ann in (int, float):
        return ann
    if ann is P:
        return "out" if param.name in OUTPUTS or (command, param.opts[0]) in OUTPUTS else "in"
    if ann is str:
        return str
    return None


def commands():
    """``[(("dataset", "generate"), click_command), ...]`` of every command."""
    import typer

    from treeform.cli.app import app

    def walk(cmd, path):
        if hasattr(cmd, "commands"):
            for name, sub in sorted(cmd.commands.items()):
                yield from walk(sub, path + (name,))
        else:
            yield path, cmd

    return list(walk(typer.main.get_command(app), ()))


def cases(base: dict) -> list:
    """``[{"command", "option", "value", "args"}]``: each swept option of each command with base
    arguments ``base[command]`` (the valid rest of the command line, with ``{out}`` for the
    case's output folder)."""
    out = []
    for path, cmd in commands():
        name = " ".join(path)
        if name not in base:
            continue
        for p in cmd.params:
            if getattr(p, "is_flag", False) or not p.opts or not p.opts[0].startswith("-"):
                continue
            kind = _kind(p, name)
            if kind is None:
                continue
            opt = p.opts[0]
            for value in WRONG[kind]:
                if (name, opt, value) in VALID or ("*", opt, value) in VALID:
                    continue
                args = list(base[name])
                if opt in args:  # the option is in the base line: replace its value
                    i = args.index(opt)
                    args[i + 1] = value
                else:
                    args += [opt, value]
                out.append({"command": name, "option": opt, "value": value, "args": [*path, *args]})
    return out


class _Late(BaseException):
    """The case's time is up (a BaseException, so that no ``except Exception`` swallows it)."""


def _run(cases_: list, fixtures: dict, limit: float) -> list:
    import contextlib
    import io
    import os
    import signal
    import time

    from treeform.cli.app import main

    def late(*_):
        raise _Late()

    signal.signal(signal.SIGALRM, late)
    results = []
    for i, c in enumerate(cases_):
        folder = Path(fixtures["work"]) / f"case{i:03d}"
        folder.mkdir(parents=True)
        fill = {**fixtures, "out": str(folder / "out")}
        args = [a.format(**fill) for a in c["args"]]
        err, std = io.StringIO(), io.StringIO()
        code, t0 = None, time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, limit)
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
                main(args)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except _Late:
            code = "timeout"
        except BaseException as exc:  # a traceback the user would see
            import traceback

            code = "exception"
            err.write("Traceback (most recent call last):\n" + "".join(traceback.format_exception(exc)))
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        left = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
        results.append({**c, "args": args, "code": code, "stderr": err.getvalue(), "left": left,
                        "seconds": round(time.perf_counter() - t0, 2)})
        os.chdir(fixtures["work"])
    return results


if __name__ == "__main__":
    fixtures = json.loads(Path(sys.argv[1]).read_text())
    todo = json.loads(Path(sys.argv[2]).read_text())
    res = _run(todo, fixtures, float(fixtures.get("limit", 30)))
    Path(sys.argv[3]).write_text(json.dumps(res, indent=1))
