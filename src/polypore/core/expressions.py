"""Safe, vectorised expressions of x, y, z, t for case-file values.

``"1e5 + 1000*9.81*(-y)"`` or ``"where(t < 500, 4*t/2000, 1) * 0.005"`` become
numpy-vectorised callables. The text is parsed with :mod:`ast` and only numbers,
the variables, named constants, arithmetic, comparisons and a whitelist of numpy
functions are accepted: nothing is executed that the whitelist does not name.
"""

from __future__ import annotations

import ast
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
        env = {"x": x, "y": y, "z": z, "t": t, **extra}
        shape = np.broadcast_shapes(*(np.shape(v) for v in env.values()))
        out = _eval(self.tree.body, env, self.params)
        return np.broadcast_to(np.asarray(out, dtype=float), shape).copy() if shape else float(out)

    @property
    def is_constant(self) -> bool:
        return not self.names


def _eval(node, env, params):
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        if node.id in env:
            return env[node.id]
        if node.id in params:
            return params[node.id]
        return CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env, params), _eval(node.right, env, params))
    if isinstance(node, ast.UnaryOp):
        return _UNOPS[type(node.op)](_eval(node.operand, env, params))
    if isinstance(node, ast.Compare):
        left = _eval(node.left, env, params)
        result = True
        for op, comp in zip(node.ops, node.comparators):
            right = _eval(comp, env, params)
            result = np.logical_and(result, _CMPOPS[type(op)](left, right))
            left = right
        return result
    if isinstance(node, ast.BoolOp):
        vals = [_eval(v, env, params) for v in node.values]
        f = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
        out = vals[0]
        for v in vals[1:]:
            out = f(out, v)
        return out
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
                raise InputError(field, f"expression {text!r}: only numbers are allowed as literals, got {sub.value!r}")
            continue
        if isinstance(sub, ast.Name):
            if sub.id in VARIABLES or sub.id in extra:
                used.add(sub.id)
            elif sub.id not in CONSTANTS and sub.id not in params and sub.id not in FUNCTIONS:
                raise InputError(field, f"expression {text!r} uses unknown name {sub.id!r}; allowed: {_allowed()}"
                                 + (f", and here also {', '.join(extra)}" if extra else ""))
            continue
        if isinstance(sub, ast.Call):
            if not isinstance(sub.func, ast.Name) or sub.func.id not in FUNCTIONS or sub.keywords:
                what = sub.func.id if isinstance(sub.func, ast.Name) else ast.unparse(sub.func)
                raise InputError(field, f"expression {text!r} calls {what!r}, which is not allowed; allowed: {_allowed()}")
            continue
        if isinstance(sub, (ast.BinOp, ast.UnaryOp, ast.Compare, ast.BoolOp, ast.IfExp)):
            if isinstance(sub, ast.BinOp) and type(sub.op) not in _BINOPS:
                raise InputError(field, f"expression {text!r}: operator {type(sub.op).__name__} is not allowed")
            continue
        raise InputError(field, f"expression {text!r}: {type(sub).__name__} is not allowed; allowed: {_allowed()}")
    return used


def parse(value, field: str, params: Mapping[str, float] | None = None, extra: tuple = ()) -> Expression:
    """Parse a case-file value (number or expression text) into an :class:`Expression`.

    Raises
    ------
    InputError
        Naming ``field``, for text that does not parse, unknown names or functions,
        or anything but arithmetic on numbers and the variables.
    """
    params = dict(params or {})
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(field, f"expected a number or an expression of x, y, z, t, got {value!r}")
    text = repr(float(value)) if not isinstance(value, str) else value.strip()
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise InputError(field, f"expression {text!r} does not parse ({exc.msg} at column {exc.offset})") from None
    used = _check(tree, field, text, params, tuple(extra))
    expr = Expression(text, field, tree, frozenset(used), params)
    try:
        with np.errstate(all="ignore"):
            expr(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), **{k: np.zeros(1) for k in extra})
    except (TypeError, ValueError) as exc:
        raise InputError(field, f"expression {text!r} cannot be evaluated: {exc}") from None
    return expr
