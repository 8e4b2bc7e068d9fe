"""The safe expression language of case files: arithmetic works, Python internals do not."""

import numpy as np
import pytest

from femcrowd.expressions import Expression, ExpressionError

X = np.array([0.0, 1.0, 2.0, 5.0])
Y = np.array([1.0, 0.5, -1.0, 0.0])


@pytest.mark.parametrize("source, expected", [
    ("0.6 * (x < 4)", 0.6 * (X < 4)),
    ("sqrt(x**2 + y**2)", np.hypot(X, Y)),
    ("where(x > 1, exp(-y), minimum(x, 0.5))", np.where(X > 1, np.exp(-Y), np.minimum(X, 0.5))),
    ("1 if t > 1 else 2", np.full(4, 1.0)),
    ("(x > 0.5) & (x < 2.5)", ((X > 0.5) & (X < 2.5)).astype(float)),
    ("0 < x <= 2", ((X > 0) & (X <= 2)).astype(float)),
    ("-x / maximum(hypot(x, y), 1e-300)", -X / np.maximum(np.hypot(X, Y), 1e-300)),
    ("pi * t", np.full(4, 2 * np.pi)),
    ("3", np.full(4, 3.0)),
])
def test_values(source, expected):
    assert np.allclose(Expression(source)(X, Y, 2.0), expected)


def test_time_dependence_is_detected():
    assert Expression("x * t").depends_on_time
    assert not Expression("x * 2").depends_on_time


@pytest.mark.parametrize("source", [
    "__import__('os').system('true')", "x.__class__", "().__class__.__bases__[0]",
    "open('/etc/passwd')", "lambda: 1", "x[0]", "np.exp(x)", "exp(x=1)", "[1, 2]",
    "'text'", "z + 1", "eval('1')", "x if", "sqrt(*x)", "{1: 2}", "(y := 2)",
])
def test_forbidden_or_malformed(source):
    with pytest.raises(ExpressionError):
        Expression(source)
