"""Safe arithmetic expressions of x, y, t (and of rho, for a speed law) from case files.

Case files are user input, so expressions are never handed to ``eval``. They
are parsed with :mod:`ast` and evaluated by walking a whitelist of node types:
numbers, the variables ``x, y, t``, a few constants, arithmetic and comparison
operators, ``a if c else b`` and calls of whitelisted numpy functions. Anything
else (attributes, subscripts, lambdas, names outside the whitelist, keyword
arguments, a call with the wrong number of arguments) is refused when the case
is loaded, before anything runs.
(A hand-written evaluator rather than a library: numexpr or sympy would add a
dependency, and sympy's parser itself calls eval.)

The cost of an evaluation is bounded (docs/case-format.md, "Expressions"):
the source is at most MAX_LENGTH characters, checked before it is parsed; its
tree at most MAX_NODES nodes and MAX_DEPTH levels deep, checked before it is
evaluated; and every number is a float64 (no Python big integers: ``10**10**10``
is inf at once, not a 10-billion-digit integer), so each node costs one numpy
operation on the arrays. Errors of floating-point arithmetic (1/0, 10.0**1000,
(-1)**0.5, 1 % 0) follow numpy and give inf or nan, not exceptions, so that
``where(x > 0, 1/x, 0)`` works; a result that is not finite anywhere it is
evaluated is an error naming the value and the point.
"""

import ast
import operator

import numpy as np

from .errors import InputError

#: the longest source (characters), checked before it is parsed: the parser's own recursion is bounded too
MAX_LENGTH = 10_000
#: the most nodes of the parsed tree (operators, names and contexts included)
MAX_NODES = 4_000
#: the deepest nesting of the parsed tree (Python's parser itself allows 200 nested parentheses)
MAX_DEPTH = 200

VARIABLES = ("x", "y", "t")
CONSTANTS = {"pi": np.float64(np.pi), "e": np.float64(np.e), "inf": np.float64(np.inf)}
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
#: the number of arguments of each function (the ufuncs' own, nin: further ones would be their `out` arrays)
ARITY = {name: 3 if name in ("where", "clip") else function.nin for name, function in FUNCTIONS.items()}

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
#: why a value is not finite, for the message
_WHY = {"inf": "a division by zero or an overflow",
        "nan": "0/0, a % 0, inf - inf, the sqrt or log of a number below 0, or one below 0 to a fractional power"}


class ExpressionError(ValueError):
    """An expression that does not parse, uses something outside the whitelist, exceeds the limits on its size,
    or gives a value that is not finite."""


class Expression:
    """A parsed, validated expression; call it with arrays ``x, y`` and a time ``t`` (or, for other
    ``variables``, evaluate it with :meth:`of`). ``origin``: the (file, key) of the case it comes from; its errors
    are then InputErrors naming them and the source, whenever it is evaluated (during a run too)."""

    def __init__(self, source, variables=VARIABLES, origin=None):
        self.source = str(source)
        self.variables = tuple(variables)
        self.origin = origin
        text = self.source.strip()
        if len(text) > MAX_LENGTH:
            self._fail(f"is {len(text)} characters long: an expression may have at most {MAX_LENGTH}")
        try:
            tree = ast.parse(text, mode="eval")
        except SyntaxError as err:
            self._fail(f"syntax error in expression: {err.msg}")
        except (RecursionError, MemoryError):   # the parser's own limits on nesting
            self._fail(f"is nested too deeply: an expression may be at most {MAX_DEPTH} levels deep")
        self._tree = tree.body
        self._bound(self._tree)
        self.names = set()
        self._check(self._tree)

    @property
    def depends_on_time(self):
        return "t" in self.names

    def _fail(self, message):
        """Raise the error of this expression: an InputError naming its origin, else an ExpressionError."""
        if self.origin is None:
            raise ExpressionError(message) from None
        file, key = self.origin
        raise InputError(file, key, self.source, message) from None

    def _bound(self, tree):
        """Refuse a tree of more than MAX_NODES nodes or MAX_DEPTH levels (walked without recursion, and no
        further than the limits)."""
        nodes, stack = 0, [(tree, 1)]
        while stack:
            node, depth = stack.pop()
            nodes += 1
            if nodes > MAX_NODES:
                self._fail(f"is too long: an expression may have at most {MAX_NODES} nodes (numbers, names, "
                           "operators)")
            if depth > MAX_DEPTH:
                self._fail(f"is nested too deeply: an expression may be at most {MAX_DEPTH} levels deep")
            stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))

    def _check(self, node):
        if isinstance(node, ast.Constant):
            if not isinstance(node.value, (int, float)) or isinstance(node.value, bool):
                self._fail(f"only numbers are allowed, not {node.value!r}")
            try:
                finite = np.isfinite(float(node.value))
            except OverflowError:
                finite = False
            if not finite:
                self._fail("a number is beyond the range of floats (about 1.8e308)")
        elif isinstance(node, ast.Name):
            if node.id not in self.variables and node.id not in CONSTANTS:
                self._fail(f"unknown name {node.id!r} (variables: {', '.join(self.variables)}; "
                           "constants: pi, e, inf)")
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
                self._fail(f"function {what!r} is not allowed (allowed: {', '.join(sorted(FUNCTIONS))})")
            if node.keywords:
                self._fail("keyword arguments are not allowed")
            wanted = ARITY[node.func.id]
            if len(node.args) != wanted:
                self._fail(f"{node.func.id}() takes {wanted} argument{'s' * (wanted > 1)}, not {len(node.args)}")
            for arg in node.args:
                self._check(arg)
        else:
            self._fail(f"{type(node).__name__} ({ast.unparse(node)!r}) is not allowed")

    def __call__(self, x, y, t=0.0):
        """Evaluate on arrays x, y (same shape); the result is a finite float array of that shape."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return self._evaluate({"x": x, "y": y, "t": np.float64(t)}, x.shape)

    def of(self, **values):
        """Evaluate with the arrays of its variables given by name, e.g. ``of(rho=r)``; a finite float array of
        their (broadcast) shape."""
        env = {name: np.asarray(values[name], float) for name in self.variables}
        return self._evaluate(env, np.broadcast_shapes(*(v.shape for v in env.values())))

    def _evaluate(self, env, shape):
        """The value with the variables of `env`, broadcast to `shape` (a new float array); an error naming a point
        where it is not finite."""
        with np.errstate(all="ignore"):   # inf and nan where they arise: where() may discard them
            try:
                value = self._eval(self._tree, {**env, **CONSTANTS})
            except (TypeError, ValueError) as err:   # e.g. -(x < 1): numpy has no negative of booleans
                self._fail(f"cannot be evaluated: {err}")
        value = np.broadcast_to(np.asarray(value, dtype=float), shape).copy()
        finite = np.isfinite(value)
        if not finite.all():
            bad = np.flatnonzero(~finite)
            k, shown = bad[0], value.flat[bad[0]]
            where = ", ".join(f"{n} = {np.broadcast_to(env[n], shape).flat[k]:.6g}" for n in self._located(env))
            if where and value.size > 1:
                where = f"{bad.size} of {value.size} points, first at {where}"
            self._fail(f"gives {shown}, not a finite number{' at ' * bool(where)}{where} "
                       f"({_WHY['nan' if np.isnan(shown) else 'inf']})")
        return value

    def _located(self, env):
        """The variables that say where a value is: none for a constant, x and y with t if it depends on it."""
        if not self.names & set(env):
            return []
        return [n for n in env if n in self.names or n in ("x", "y")]

    def _eval(self, node, env):
        ev = self._eval
        if isinstance(node, ast.Constant):
            return np.float64(node.value)   # float64 arithmetic: no Python big integers (10**10**10 is inf)
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
