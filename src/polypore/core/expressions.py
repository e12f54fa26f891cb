"""Safe, vectorised expressions of x, y, z, t for case-file values.

``"1e5 + 1000*9.81*(-y)"`` or ``"where(t < 500, 4*t/2000, 1) * 0.005"`` become
numpy-vectorised callables. The text is parsed with :mod:`ast` and only numbers,
the variables, named constants, arithmetic, comparisons and a whitelist of numpy
functions are accepted: nothing is executed that the whitelist does not name.

Evaluation is bounded: the text's length and its tree's size and depth are capped, and
every operand is a float64 (numbers, parameters and variables alike), so ``2**9999999999``
is ``inf`` in constant time instead of a Python integer that grows without bound, and
``1/0`` is ``inf`` instead of an exception. A value that is not finite where a field is
evaluated is an :class:`InputError` naming the field and a point where it happens.
"""

from __future__ import annotations

import ast
import keyword
import operator
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from .errors import InputError

VARIABLES = ("x", "y", "z", "t")
CONSTANTS = {"pi": np.pi, "e": np.e}
FUNCTIONS: dict[str, Callable] = {
    name: getattr(np, name)
    for name in ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh",
                 "exp", "log", "log10", "sqrt", "abs", "minimum", "maximum", "where", "clip", "sign",
                 "heaviside", "floor", "ceil", "hypot")
}
# positional arguments each function takes (numpy's optional ones, e.g. out=, are not offered)
_ARITY = {name: 1 for name in FUNCTIONS} | {"arctan2": 2, "minimum": 2, "maximum": 2, "heaviside": 2,
                                          "hypot": 2, "where": 3, "clip": 3}
# Caps that bound parse and evaluation time: case-file expressions are a line or two; the depth
# cap keeps the recursive evaluator far from Python's recursion limit.
MAX_LENGTH = 10_000   # characters
MAX_NODES = 2_000     # syntax-tree nodes
MAX_DEPTH = 200       # syntax-tree nesting
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNOPS = {ast.UAdd: operator.pos, ast.USub: operator.neg, ast.Not: np.logical_not}
_CMPOPS = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge,
           ast.Eq: operator.eq, ast.NotEq: operator.ne}


def _allowed() -> str:
    return f"variables {', '.join(VARIABLES)}, constants {', '.join(CONSTANTS)}, functions {', '.join(FUNCTIONS)}"


@dataclass(frozen=True)
class Expression:
    """A parsed scalar expression; call it with arrays x, y, z, t (broadcast together).

    Attributes
    ----------
    text : str
        The source text.
    field : str
        Dotted case-file key it came from (for error messages).
    names : frozenset of str
        Variables the expression uses.
    """

    text: str
    field: str
    tree: ast.Expression
    names: frozenset
    params: Mapping[str, float]

    def __call__(self, x=0.0, y=0.0, z=0.0, t=0.0, **extra):
        """Values at the given points, broadcast together; an InputError naming the field if
        any value is not finite (the first such point is quoted)."""
        env, shape = _environment(x, y, z, t, extra)
        out = np.broadcast_to(self.evaluate_in(env), shape)
        bad = ~np.isfinite(out)
        if bad.any():
            raise InputError(self.field, self.not_finite_message(out, bad, env, shape))
        return out.copy() if shape else float(out)

    def evaluate_in(self, env) -> np.ndarray:
        # errors ignored: where(x > 0, 1/x, 0) divides by zero in the branch it discards, so
        # only the result is checked; float64 operands make 1/0 inf rather than an exception
        try:
            with np.errstate(all="ignore"):
                return np.asarray(_eval(self.tree.body, env, self.params), dtype=float)
        except (ArithmeticError, TypeError, ValueError) as exc:
            raise InputError(self.field, f"expression {self.text!r} cannot be evaluated: {exc}") from None

    def not_finite_message(self, out, bad, env, shape) -> str:
        what = (f"{'inf' if np.isinf(out[bad]).any() else 'nan'} (a division by zero, an overflow, or a function "
                "outside its domain such as log or sqrt of a negative number); allowed: finite values")
        if not self.names and not shape:
            return f"expression {self.text!r} evaluates to {what}"
        i = np.unravel_index(int(np.flatnonzero(bad)[0]), shape) if shape else ()
        val = {k: float(np.broadcast_to(v, shape)[i]) for k, v in env.items()}
        coords = (["x", "y"] + (["z"] if np.any(env["z"] != 0) else [])) if shape else []
        parts = ([f"({', '.join(coords)}) = ({', '.join(f'{val[k]:.6g}' for k in coords)})"] if coords else []) \
            + [f"{k} = {val[k]:.6g}" for k in env if k in self.names and k not in coords]
        count = f" at {int(bad.sum())} of {bad.size} points" if shape else ""
        return f"expression {self.text!r} is not finite{count}, e.g. at {', '.join(parts)}: {what}"

    @property
    def is_constant(self) -> bool:
        return not self.names


def _environment(x, y, z, t, extra):
    # float64 throughout: a Python int operand (t = 2) would make t**9999999999 exact and unbounded
    env = {k: np.asarray(v, dtype=float) for k, v in {"x": x, "y": y, "z": z, "t": t, **extra}.items()}
    return env, np.broadcast_shapes(*(v.shape for v in env.values()))


def _as_float(v):
    # truth values are 0 and 1, as in Python: -(x > 0) and (x > 0) * 5 work on arrays too
    return np.asarray(v, dtype=float) if np.ndim(v) else np.float64(v)


def _eval(node, env, params):
    if isinstance(node, ast.Constant):
        return np.float64(node.value)
    if isinstance(node, ast.Name):
        if node.id in env:
            return env[node.id]
        if node.id in params:
            return params[node.id]
        return np.float64(CONSTANTS[node.id])
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env, params), _eval(node.right, env, params))
    if isinstance(node, ast.UnaryOp):
        return _as_float(_UNOPS[type(node.op)](_eval(node.operand, env, params)))
    if isinstance(node, ast.Compare):
        left = _eval(node.left, env, params)
        result = True
        for op, comp in zip(node.ops, node.comparators):
            right = _eval(comp, env, params)
            result = np.logical_and(result, _CMPOPS[type(op)](left, right))
            left = right
        return _as_float(result)
    if isinstance(node, ast.BoolOp):
        vals = [_eval(v, env, params) for v in node.values]
        f = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
        out = vals[0]
        for v in vals[1:]:
            out = f(out, v)
        return _as_float(out)
    if isinstance(node, ast.IfExp):
        return np.where(_eval(node.test, env, params), _eval(node.body, env, params), _eval(node.orelse, env, params))
    if isinstance(node, ast.Call):
        return FUNCTIONS[node.func.id](*[_eval(a, env, params) for a in node.args])
    raise AssertionError(f"unchecked node {type(node).__name__}")  # parse() rejects everything else


def _check(node, field: str, text: str, params, extra=()) -> set:
    used = set()
    for sub in ast.walk(node):
        if isinstance(sub, (ast.Expression, ast.Load, ast.operator, ast.unaryop, ast.cmpop, ast.boolop)):
            continue
        if isinstance(sub, ast.Constant):
            if isinstance(sub.value, bool) or not isinstance(sub.value, (int, float)):
                raise InputError(field, f"expression {_clip(text)}: only numbers are allowed as literals, got {sub.value!r}")
            if not _finite(sub.value):
                lit = ast.get_source_segment(text, sub) or _short(sub.value)
                raise InputError(field, f"expression {_clip(text)}: the number {_short(lit)} overflows double "
                                 "precision; allowed: numbers of magnitude below 1.8e308")
            continue
        if isinstance(sub, ast.Name):
            if sub.id in VARIABLES or sub.id in extra:
                used.add(sub.id)
            elif sub.id not in CONSTANTS and sub.id not in params and sub.id not in FUNCTIONS:
                raise InputError(field, f"expression {_clip(text)} uses unknown name {sub.id!r}; allowed: {_allowed()}"
                                 + (f", and here also {', '.join(extra)}" if extra else ""))
            continue
        if isinstance(sub, ast.Call):
            if not isinstance(sub.func, ast.Name) or sub.func.id not in FUNCTIONS or sub.keywords:
                what = sub.func.id if isinstance(sub.func, ast.Name) else ast.unparse(sub.func)
                raise InputError(field, f"expression {_clip(text)} calls {what!r}, which is not allowed; allowed: {_allowed()}")
            n = _ARITY[sub.func.id]
            if len(sub.args) != n or any(isinstance(a, ast.Starred) for a in sub.args):
                raise InputError(field, f"expression {_clip(text)}: {sub.func.id} takes {n} argument{'s' * (n > 1)}, "
                                 f"got {len(sub.args)}")
            continue
        if isinstance(sub, (ast.BinOp, ast.UnaryOp, ast.Compare, ast.BoolOp, ast.IfExp)):
            if isinstance(sub, ast.BinOp) and type(sub.op) not in _BINOPS:
                raise InputError(field, f"expression {_clip(text)}: operator {type(sub.op).__name__} is not allowed")
            continue
        raise InputError(field, f"expression {_clip(text)}: {type(sub).__name__} is not allowed; allowed: {_allowed()}")
    return used


def _finite(v) -> bool:
    try:
        return bool(np.isfinite(float(v)))
    except OverflowError:  # an integer beyond the float range
        return False


def _short(v) -> str:
    r = v if isinstance(v, str) else repr(v)
    return r if len(r) <= 40 else f"{r[:12]}…({len(r)} digits)"


def _check_size(tree: ast.Expression, field: str, text: str) -> None:
    # iterative: a recursive walk would itself hit the recursion limit on the trees it must reject
    nodes, stack = 0, [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        nodes += 1
        if nodes > MAX_NODES:
            raise InputError(field, f"expression of {len(text)} characters has more than {MAX_NODES} terms and "
                             "operators; allowed: at most that many (use [parameters] for repeated values)")
        if depth > MAX_DEPTH:
            raise InputError(field, f"expression {_clip(text)} is nested more than {MAX_DEPTH} levels deep; allowed: "
                             f"at most {MAX_DEPTH} (a long sum a + b + c + … nests one level per term)")
        stack.extend((c, depth + 1) for c in ast.iter_child_nodes(node)
                     if not isinstance(c, (ast.expr_context, ast.operator, ast.unaryop, ast.cmpop, ast.boolop)))


def _clip(text: str) -> str:
    return repr(text) if len(text) <= 80 else repr(text[:60] + " … " + text[-12:])


def _check_params(params, field: str, used: set, extra: tuple) -> None:
    # a parameter named like a variable or function is silently shadowed (variables win) or
    # shadows (constants): either way the expression means something else than it reads
    for name in params:
        what = ("a coordinate/time variable in expressions" if name in VARIABLES
                else "a function in expressions" if name in FUNCTIONS
                else "a constant in expressions" if name in CONSTANTS
                else f"a variable of {field}, which uses it" if name in extra and name in used else None)
        if what:
            raise InputError(f"params.{name}", f"the name {name!r} is {what}; rename the parameter (names "
                             f"taken: {_allowed()}" + (f"; in {field} also {', '.join(extra)}" if extra else "") + ")")
        if not name.isidentifier() or keyword.iskeyword(name):
            raise InputError(f"params.{name}", f"{name!r} cannot be used in an expression; allowed: names of "
                             "letters, digits and _ that do not start with a digit")


def parse(value, field: str, params: Mapping[str, float] | None = None, extra: tuple = ()) -> Expression:
    """Parse a case-file value (number or expression text) into an :class:`Expression`.

    Raises
    ------
    InputError
        Naming ``field``, for text that does not parse, is longer, larger or deeper than
        :data:`MAX_LENGTH`, :data:`MAX_NODES`, :data:`MAX_DEPTH`, uses unknown names or
        functions or anything but arithmetic on numbers and the variables, for a constant
        expression that is not finite (``1/0``), and naming the parameter, for a parameter
        whose name is taken by a variable, function or constant.
    """
    params = {k: np.float64(v) for k, v in (params or {}).items()}
    extra = tuple(extra)
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(field, f"expected a number or an expression of x, y, z, t, got {value!r}")
    if not isinstance(value, str):
        if not _finite(value):
            raise InputError(field, f"must be a finite number, got {_short(value)}")
        text = repr(float(value))
    else:
        text = value.strip()
    if len(text) > MAX_LENGTH:
        raise InputError(field, f"expression of {len(text)} characters is too long; allowed: at most {MAX_LENGTH} "
                         "(use [parameters] for repeated values)")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise InputError(field, f"expression {_clip(text)} does not parse ({exc.msg} at column {exc.offset})") from None
    except (RecursionError, MemoryError, ValueError):
        # CPython's parser gives up on deep nesting with these rather than a SyntaxError
        raise InputError(field, f"expression {_clip(text)} is nested too deeply to parse; allowed: at most "
                         f"{MAX_DEPTH} levels") from None
    _check_size(tree, field, text)
    used = _check(tree, field, text, params, extra)
    _check_params(params, field, used, extra)
    expr = Expression(text, field, tree, frozenset(used), params)
    # a probe evaluation reports what the checks above cannot see (operand types) now, not mid-run;
    # only a constant's value is known here, so only a constant is checked for finiteness
    env, _ = _environment(*([np.zeros(1)] * 4), {k: np.zeros(1) for k in extra})
    probe = expr.evaluate_in(env)
    if not used and not np.all(np.isfinite(probe)):
        raise InputError(field, expr.not_finite_message(probe, ~np.isfinite(probe), env, ()))
    return expr
