"""Safe arithmetic expressions of x, y, t (and of rho, for a speed law) from case files.

Case files are user input, so expressions are never handed to ``eval``. They
are parsed with :mod:`ast` and evaluated by walking a whitelist of node types:
numbers, the variables ``x, y, t``, a few constants, arithmetic and comparison
operators, ``a if c else b`` and calls of whitelisted numpy functions. Anything
else (attributes, subscripts, lambdas, names outside the whitelist, keyword
arguments) is refused when the case is loaded, before anything runs.
(A hand-written evaluator rather than a library: numexpr or sympy would add a
dependency, and sympy's parser itself calls eval.)
"""

import ast
import operator

import numpy as np

VARIABLES = ("x", "y", "t")
CONSTANTS = {"pi": np.pi, "e": np.e, "inf": np.inf}
FUNCTIONS = {
    name: getattr(np, name)
    for name in (
        "sqrt", "exp", "log", "log10", "sin", "cos", "tan", "arctan2", "arctan",
        "arcsin", "arccos", "sinh", "cosh", "tanh", "abs", "minimum", "maximum",
        "where", "sign", "floor", "ceil", "clip", "hypot", "heaviside",
        "logical_and", "logical_or", "logical_not",
    )
}
FUNCTIONS.update({"min": np.minimum, "max": np.maximum, "atan2": np.arctan2})

_BINARY = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: operator.mod,
    ast.FloorDiv: operator.floordiv, ast.BitAnd: np.logical_and, ast.BitOr: np.logical_or,
}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos, ast.Not: np.logical_not}
_COMPARE = {
    ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
    ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne,
}


class ExpressionError(ValueError):
    """An expression that does not parse or uses something outside the whitelist."""


class Expression:
    """A parsed, validated expression; call it with arrays ``x, y`` and a time ``t`` (or, for other
    ``variables``, evaluate it with :meth:`of`)."""

    def __init__(self, source, variables=VARIABLES):
        self.source = str(source)
        self.variables = tuple(variables)
        try:
            tree = ast.parse(self.source.strip(), mode="eval")
        except SyntaxError as err:
            raise ExpressionError(f"syntax error in expression: {err.msg}") from None
        self._tree = tree.body
        self.names = set()
        self._check(self._tree)

    @property
    def depends_on_time(self):
        return "t" in self.names

    def _check(self, node):
        if isinstance(node, ast.Constant):
            if not isinstance(node.value, (int, float)) or isinstance(node.value, bool):
                raise ExpressionError(f"only numbers are allowed, not {node.value!r}")
        elif isinstance(node, ast.Name):
            if node.id not in self.variables and node.id not in CONSTANTS:
                raise ExpressionError(
                    f"unknown name {node.id!r} (variables: {', '.join(self.variables)}; constants: pi, e)")
            self.names.add(node.id)
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            self._check(node.operand)
        elif isinstance(node, ast.BoolOp):
            for value in node.values:
                self._check(value)
        elif isinstance(node, ast.Compare) and all(type(op) in _COMPARE for op in node.ops):
            for child in [node.left, *node.comparators]:
                self._check(child)
        elif isinstance(node, ast.IfExp):
            for child in (node.test, node.body, node.orelse):
                self._check(child)
        elif isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                what = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
                raise ExpressionError(f"function {what!r} is not allowed "
                                      f"(allowed: {', '.join(sorted(FUNCTIONS))})")
            if node.keywords:
                raise ExpressionError("keyword arguments are not allowed")
            for arg in node.args:
                self._check(arg)
        else:
            raise ExpressionError(f"{type(node).__name__} ({ast.unparse(node)!r}) is not allowed")

    def __call__(self, x, y, t=0.0):
        """Evaluate on arrays x, y (same shape); the result is a float array of that shape."""
        env = {"x": np.asarray(x, float), "y": np.asarray(y, float), "t": float(t), **CONSTANTS}
        with np.errstate(all="ignore"):
            value = self._eval(self._tree, env)
        return np.broadcast_to(np.asarray(value, dtype=float), env["x"].shape).copy()

    def of(self, **values):
        """Evaluate with the arrays of its variables given by name, e.g. ``of(rho=r)``; a float array of
        their (broadcast) shape."""
        env = {name: np.asarray(values[name], float) for name in self.variables}
        with np.errstate(all="ignore"):
            value = self._eval(self._tree, {**env, **CONSTANTS})
        shape = np.broadcast_shapes(*(v.shape for v in env.values()))
        return np.broadcast_to(np.asarray(value, dtype=float), shape).copy()

    def _eval(self, node, env):
        ev = self._eval
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name):
            return env[node.id]
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](ev(node.left, env), ev(node.right, env))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](ev(node.operand, env))
        if isinstance(node, ast.BoolOp):
            combine = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
            values = [ev(v, env) for v in node.values]
            out = values[0]
            for value in values[1:]:
                out = combine(out, value)
            return out
        if isinstance(node, ast.Compare):
            left, out = ev(node.left, env), True
            for op, right_node in zip(node.ops, node.comparators):
                right = ev(right_node, env)
                out = np.logical_and(out, _COMPARE[type(op)](left, right))
                left = right
            return out
        if isinstance(node, ast.IfExp):
            return np.where(ev(node.test, env), ev(node.body, env), ev(node.orelse, env))
        return FUNCTIONS[node.func.id](*[ev(a, env) for a in node.args])
