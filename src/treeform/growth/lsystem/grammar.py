"""Parametric, bracketed, stochastic L-systems: the grammar (seed 004 §4; Prusinkiewicz & Lindenmayer).

A grammar is plain text (the species presets live in ``growth/species/lsystems/*.lsys``)::

    # comment
    define angle = 40                 # constants; callers may override them (``defines=``)
    axiom: !(0.2) A(8)
    derivations: 5
    tropism: 0 -1 0 0.1               # direction x y z and susceptibility e (optional)
    A(l) : l > 1 -> F(l) [&(angle) /(137.5) A(l*0.6)] A(l*0.8)
    A(l) -> 0.7 : L(leaf_size) ; 0.3 : %       # stochastic: probability : successor ; ...

A module is one letter, one turtle symbol of ``+ - & ^ / \\ | [ ] ! $ %``, or ``@`` and a
letter, optionally followed by parameters in parentheses. A rule ``PRED(params) [: condition]
-> successor`` rewrites every module of that name and parameter count whose condition holds;
the first such rule in file order applies (deterministic), and a rule whose successor lists
``probability : successor`` alternatives separated by ``;`` picks one of them with those
weights. Parameters, conditions and probabilities are arithmetic expressions over the rule's
parameters, the defines and ``uniform(a, b)``, ``normal(m, s)``, ``random()``, ``min``, ``max``,
``abs``, ``sqrt``, ``sin``, ``cos``, ``tan``, ``exp``, ``floor``, ``pi`` (degrees are plain numbers).
Expressions are parsed with :mod:`ast` and only those constructs are accepted: a grammar file
cannot run arbitrary code.
"""

from __future__ import annotations

import ast
import math
import random
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_finite
from treeform._shared.errors import InputError

__all__ = ["LSystem", "Module", "parse_lsystem", "load_preset", "preset_names", "PRESET_DIR", "MAX_MODULES"]

PRESET_DIR = Path(__file__).resolve().parent.parent / "species" / "lsystems"
"""Folder of the species presets (``<species>.lsys``; ``generic.lsys`` for any other)."""

MAX_MODULES = 400_000
"""A derivation that grows a string past this many modules stops with an InputError."""

TURTLE_SYMBOLS = "+-&^/\\|[]!$%"

Module = tuple
"""A module: ``(name, params)`` with ``params`` a tuple of floats."""

_FUNCTIONS = ("uniform", "normal", "random", "min", "max", "abs", "sqrt", "sin", "cos", "tan", "exp", "floor")
_CONSTANTS = {"pi": math.pi}
_BINOPS = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow, ast.Mod, ast.FloorDiv)
_CMPOPS = (ast.Eq, ast.NotEq, ast.Lt, ast.LtE, ast.Gt, ast.GtE)
_NAME = re.compile(r"@?[A-Za-z]")


def _check_expr(text: str, names: set, where: str) -> str:
    """Validate an expression against the whitelist; return it normalised (``&&`` -> ``and``)."""
    src = text.strip().replace("&&", " and ").replace("||", " or ")
    if not src:
        raise InputError(f"{where}: empty expression")
    try:
        tree = ast.parse(src, mode="eval")
    except SyntaxError:
        raise InputError(f"{where}: cannot parse expression {text.strip()!r}") from None
    for node in ast.walk(tree):
        ok = isinstance(node, (ast.Expression, ast.BinOp, ast.UnaryOp, ast.BoolOp, ast.Compare, ast.IfExp,
                               ast.Load, ast.USub, ast.UAdd, ast.Not, ast.And, ast.Or) + _BINOPS + _CMPOPS)
        if isinstance(node, ast.Constant):
            ok = isinstance(node.value, (int, float))
        elif isinstance(node, ast.Name):
            if node.id not in names and node.id not in _FUNCTIONS and node.id not in _CONSTANTS:
                raise InputError(f"{where}: unknown name {node.id!r} in {text.strip()!r}")
            ok = True
        elif isinstance(node, ast.Call):
            ok = isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS and not node.keywords
            if not ok:
                raise InputError(f"{where}: only {', '.join(_FUNCTIONS)} may be called, in {text.strip()!r}")
        if not ok:
            raise InputError(f"{where}: {type(node).__name__} is not allowed in {text.strip()!r}")
    return src


def _split_top(text: str, sep: str) -> list[str]:
    """Split at ``sep`` outside parentheses."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == sep and depth == 0:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur))
    return out


def _tokenize(text: str, where: str) -> list[tuple[str, list[str]]]:
    """A module string -> [(name, [parameter expression, ...]), ...]."""
    mods, i, n = [], 0, len(text)
    while i < n:
        ch = text[i]
        if ch.isspace():
            i += 1
            continue
        m = _NAME.match(text, i)
        if m:
            name, i = m.group(0), m.end()
        elif ch in TURTLE_SYMBOLS:
            name, i = ch, i + 1
        else:
            raise InputError(f"{where}: unexpected character {ch!r} in {text.strip()!r}")
        args: list[str] = []
        j = i
        while j < n and text[j] == " ":
            j += 1
        if j < n and text[j] == "(":
            depth, k = 0, j
            while k < n:
                if text[k] == "(":
                    depth += 1
                elif text[k] == ")":
                    depth -= 1
                    if depth == 0:
                        break
                k += 1
            if depth != 0:
                raise InputError(f"{where}: unbalanced parentheses in {text.strip()!r}")
            inner = text[j + 1:k]
            args = [a for a in _split_top(inner, ",")] if inner.strip() else []
            i = k + 1
        mods.append((name, args))
    return mods


@dataclass
class _Rule:
    name: str
    arity: int
    cond: object  # compiled callable or None
    cond_text: str
    choices: list  # [(weight callable, successor callable)]
    line: int


@dataclass
class LSystem:
    """A parsed grammar: axiom, rules, defines, derivation count and tropism.

    Build with :func:`parse_lsystem` or :func:`load_preset`; rewrite with :meth:`derive`.
    """

    axiom: list
    rules: dict
    defines: dict
    derivations: int
    tropism: tuple = (0.0, -1.0, 0.0, 0.0)
    name: str = ""
    source: str = ""
    _globals: dict = field(default_factory=dict, repr=False)

    def with_defines(self, defines: dict | None) -> "LSystem":
        """The same grammar re-parsed with some defines overridden (unknown names are an error)."""
        if not defines:
            return self
        return parse_lsystem(self.source, defines=defines, name=self.name)

    def derive(self, axiom=None, *, steps: int | None = None, seed=0) -> list:
        """Rewrite ``axiom`` (default: the grammar's) ``steps`` times (default: ``derivations``).

        Parameters
        ----------
        axiom : list of (name, params), optional
        steps : int, optional
        seed : int or numpy.random.Generator
            Drives ``uniform``/``normal``/``random`` and the stochastic choices: same seed, same string.

        Returns
        -------
        list of (name, tuple of float)
        """
        rng = random.Random(_int_seed(seed))
        g = self._globals
        g["uniform"] = rng.uniform
        g["normal"] = rng.gauss
        g["random"] = rng.random
        steps = self.derivations if steps is None else int(steps)
        rules = self.rules
        # The string is kept as a list of items: a module that some rule rewrites, or a list (a run)
        # of modules none does. A run never changes again, so each step carries it over by reference
        # and only the rewritable modules are visited (rules, conditions and random draws in the
        # same order as a scan of the whole string: the same result, without copying the grown
        # part of the string at every step).
        string: list = []
        start = list(self.axiom if axiom is None else axiom)
        _append_split(string, start, _rewritable(start, rules))
        split: dict = {}  # successor -> where its rewritable modules are: the same on every call
        for _ in range(steps):
            out: list = []
            changed = False
            count = 0
            for mod in string:
                if type(mod) is list:
                    out.append(mod)
                    count += len(mod)
                    continue
                p = mod[1]
                for rule in rules[(mod[0], len(p))]:
                    if rule.cond is not None and not rule.cond(*p):
                        continue
                    if len(rule.choices) == 1:
                        succ = rule.choices[0][1]
                    else:
                        w = [max(float(c[0](*p)), 0.0) for c in rule.choices]
                        tot = sum(w)
                        r = rng.random() * tot if tot > 0 else 0.0
                        k = 0
                        while k < len(w) - 1 and r >= w[k]:
                            r -= w[k]
                            k += 1
                        succ = rule.choices[k][1]
                    mods = succ(*p)
                    at = split.get(succ)
                    if at is None:
                        at = split[succ] = _rewritable(mods, rules)
                    _append_split(out, mods, at)
                    count += len(mods)
                    changed = True
                    break
                else:
                    out.append(mod)
                    count += 1
                if count > MAX_MODULES:
                    raise InputError(f"L-system {self.name or ''}: the string grew past {MAX_MODULES} modules "
                                     "(fewer derivations or a smaller density)".replace("  ", " "))
            string = out
            if not changed:
                break
        return [m for item in string for m in (item if type(item) is list else (item,))]


def _rewritable(modules, rules: dict) -> tuple:
    """Indices of the modules some rule rewrites."""
    return tuple(j for j, m in enumerate(modules) if (m[0], len(m[1])) in rules)


def _append_split(out: list, modules: list, at) -> None:
    """Append ``modules`` to ``out`` as :meth:`LSystem.derive` keeps its string: the rewritable
    ones (indices ``at``) each an item, the runs between them as lists (:func:`_append_run`)."""
    prev = 0
    for j in at:
        if j > prev:
            _append_run(out, modules[prev:j])
        out.append(modules[j])
        prev = j + 1
    if prev < len(modules):
        _append_run(out, modules[prev:])


def _append_run(out: list, run: list) -> None:
    """Append a run of modules no rule rewrites (a list ``out`` may keep) to a derivation's string."""
    if out and type(out[-1]) is list:
        out[-1].extend(run)
    else:
        out.append(run)


def _int_seed(seed) -> int:
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(0, 2**63 - 1))
    if seed is None:
        return 0
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError(f"seed: expected an integer or a numpy Generator, got {seed!r}")
    return int(seed)


def _compile_successor(text: str, params: list[str], names: set, g: dict, where: str):
    """Successor text -> callable(*params) returning a list of (name, tuple) modules."""
    mods = _tokenize(text, where)
    parts = []
    for name, args in mods:
        exprs = [_check_expr(a, names, where) for a in args]
        tup = "(" + "".join(f"({e}), " for e in exprs) + ")"
        parts.append(f"({name!r}, {tup})")
    src = f"lambda {', '.join(params)}: [{', '.join(parts)}]"
    return eval(compile(src, f"<{where}>", "eval"), g)  # noqa: S307 (whitelisted AST only)


def _compile_expr(text: str, params: list[str], names: set, g: dict, where: str):
    e = _check_expr(text, names, where)
    return eval(compile(f"lambda {', '.join(params)}: ({e})", f"<{where}>", "eval"), g)  # noqa: S307


def parse_lsystem(text: str, *, defines: dict | None = None, name: str = "") -> LSystem:
    """Parse a grammar (module docstring) into an :class:`LSystem`.

    Parameters
    ----------
    text : str
    defines : dict, optional
        Values replacing the grammar's ``define`` lines (each name must be defined there).
    name : str
        For error messages.

    Returns
    -------
    LSystem

    Raises
    ------
    InputError
        A line that does not parse, an unknown name, a forbidden construct, a bad define.

    Examples
    --------
    >>> ls = parse_lsystem("define a = 2\\naxiom: A(1)\\nderivations: 3\\nA(x) : x < 4 -> F(x) A(x*a)")
    >>> [m[0] for m in ls.derive()], ls.derive()[-1]
    (['F', 'F', 'A'], ('A', (4.0,)))
    """
    if not isinstance(text, str):
        raise InputError(f"L-system: expected the grammar text, got {type(text).__name__}")
    where0 = f"L-system {name}".strip()
    g: dict = {"__builtins__": {}, **_CONSTANTS, "min": min, "max": max, "abs": abs, "sqrt": math.sqrt,
               "sin": lambda d: math.sin(math.radians(d)), "cos": lambda d: math.cos(math.radians(d)),
               "tan": lambda d: math.tan(math.radians(d)), "exp": math.exp, "floor": math.floor,
               "uniform": random.uniform, "normal": random.gauss, "random": random.random}
    defs: dict = {}
    axiom_text, derivations, tropism = None, 1, (0.0, -1.0, 0.0, 0.0)
    rule_lines = []
    for level, label, ln, line in _lines(text, name):
        where = f"L-system {label} line {ln}"
        if line.startswith("define "):
            key, _, val = line[7:].partition("=")
            key = key.strip()
            if not key.isidentifier() or not val.strip():
                raise InputError(f"{where}: expected 'define NAME = expression'")
            defs[key] = float(eval(compile(_check_expr(val, set(defs), where), where, "eval"), g, dict(defs)))  # noqa: S307
        elif line.startswith("axiom:"):
            axiom_text = line[6:]
        elif line.startswith("derivations:"):
            try:
                derivations = int(line[12:])
            except ValueError:
                raise InputError(f"{where}: expected 'derivations: INTEGER'") from None
            if not 0 <= derivations <= 64:
                raise InputError(f"{where}: derivations must be 0..64")
        elif line.startswith("tropism:"):
            try:
                tropism = tuple(float(v) for v in line[8:].split())
            except ValueError:
                tropism = ()
            if len(tropism) != 4:
                raise InputError(f"{where}: expected 'tropism: x y z strength'")
        elif "->" in line:
            rule_lines.append((level, where, line))
        else:
            raise InputError(f"{where}: not a define, axiom, derivations, tropism or rule: {line!r}")
    if defines:
        for k, v in defines.items():
            if k not in defs:
                raise InputError(f"{where0}: unknown define {k!r} (known: {', '.join(sorted(defs)) or 'none'})")
            defs[k] = check_finite(v, f"{where0}: define {k!r}")
    g.update(defs)
    if axiom_text is None:
        raise InputError(f"{where0}: no 'axiom:' line")
    names = set(defs)
    axiom = _compile_successor(axiom_text, [], names, g, f"{where0} axiom")()
    rules: dict = {}
    owner: dict = {}  # predecessor -> the deepest file (extending one) that rewrites it
    for level, where, line in rule_lines:
        lhs, _, rhs = line.partition("->")
        head, _, cond_text = lhs.partition(":")
        pred = _tokenize(head, where)
        if len(pred) != 1:
            raise InputError(f"{where}: a rule rewrites exactly one module, got {head.strip()!r}")
        pname, params = pred[0][0], [a.strip() for a in pred[0][1]]
        if pname in "[]":
            raise InputError(f"{where}: brackets cannot be rewritten")
        for p in params:
            if not p.isidentifier() or p in _FUNCTIONS or p in _CONSTANTS:
                raise InputError(f"{where}: parameter {p!r} must be a plain name")
        local = names | set(params)
        cond_text = cond_text.strip()
        cond = None if cond_text in ("", "*") else _compile_expr(cond_text, params, local, g, where)
        alts = _split_top(rhs, ";")
        choices = []
        if len(alts) == 1:
            choices.append((None, _compile_successor(alts[0], params, local, g, where)))
        else:
            for alt in alts:
                wt, sep, succ = alt.partition(":")
                if not sep:
                    raise InputError(f"{where}: stochastic alternatives are 'probability : successor ; ...'")
                choices.append((_compile_expr(wt, params, local, g, where),
                                _compile_successor(succ, params, local, g, where)))
        key = (pname, len(params))
        if owner.get(key, level) < level:  # an extending file replaces the base's rules for this module
            rules[key] = []
        owner[key] = level
        rules.setdefault(key, []).append(_Rule(pname, len(params), cond, cond_text, choices, where))
    return LSystem(axiom=axiom, rules=rules, defines=defs, derivations=derivations, tropism=tropism, name=name,
                   source=text, _globals=g)


def _lines(text: str, name: str, depth: int = 0):
    """(level, file label, line number, line) of a grammar, comments stripped; an ``extends: BASE``
    line first yields the base preset's lines at a lower level (later defines override earlier ones)."""
    own = []
    base = None
    for ln, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("extends:"):
            base = line[8:].strip()
            if depth >= 4 or base not in preset_names():
                raise InputError(f"L-system {name} line {ln}: cannot extend {base!r} "
                                 f"(one of {', '.join(preset_names())}, at most 4 deep)")
            continue
        own.append((-depth, name or "grammar", ln, line))  # shallower files win
    if base is not None:
        yield from _lines((PRESET_DIR / f"{base}.lsys").read_text(encoding="utf-8"), base, depth + 1)
    yield from own


def preset_names() -> tuple[str, ...]:
    """Names of the shipped presets (``generic`` and one per species)."""
    return tuple(sorted(p.stem for p in PRESET_DIR.glob("*.lsys")))


def load_preset(name: str, *, defines: dict | None = None) -> LSystem:
    """A shipped species preset, or a grammar file when ``name`` is a path to a ``.lsys`` file.

    Examples
    --------
    >>> "generic" in preset_names() and load_preset("oak").derivations > 0
    True
    """
    if isinstance(name, (str, Path)) and str(name).endswith(".lsys"):
        path = Path(name)
        if not path.is_file():
            raise InputError(f"L-system file not found: {path}")
    else:
        if not isinstance(name, str) or name not in preset_names():
            raise InputError(f"L-system preset: unknown {name!r} (one of {', '.join(preset_names())}, or a .lsys file)")
        path = PRESET_DIR / f"{name}.lsys"
    return parse_lsystem(path.read_text(encoding="utf-8"), defines=defines, name=path.stem)
