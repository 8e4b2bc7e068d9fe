"""The safe expression language of case files: arithmetic works, Python internals do not."""

import numpy as np
import pytest

from femcrowd.errors import InputError
from femcrowd.expressions import ARITY, FUNCTIONS, MAX_DEPTH, MAX_LENGTH, MAX_NODES, Expression, ExpressionError

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


def balanced_sum(leaves):
    """x + x + ... as a balanced tree of `leaves` terms: many nodes, little depth."""
    return "x" if leaves == 1 else f"({balanced_sum(leaves // 2)}) + ({balanced_sum(leaves - leaves // 2)})"


@pytest.mark.parametrize("source", ["x**2", "x**3", "(x + 1)**-1", "y**0.5 if t > 5 else y**2", "1/3 * x", "300 / 208",
                                    "7 // 2 + 7 % 3 * x", "2**10 - x", "(x > 1) * 3 + 2 * pi * t"])
def test_numbers_are_floats_with_the_values_of_python_numbers(source):
    """Integers are evaluated as float64 (no big integers), and that changes no value of an ordinary expression:
    the same bits as Python's own evaluation of the source on these arrays."""
    expected = eval(source, {"x": X, "y": np.abs(Y), "t": 2.0, "pi": np.pi})  # trusted test input
    assert np.array_equal(Expression(source)(X, np.abs(Y), 2.0), np.broadcast_to(expected, X.shape))


@pytest.mark.parametrize("source, words", [
    ("2**2**2**2**2", "gives inf, not a finite number (a division by zero or an overflow)"),  # 10**10**10: tests/cli
    ("1/0", "gives inf"), ("1 % 0", "gives nan"), ("10.0**1000", "gives inf"), ("(-1)**0.5", "gives nan"),
    ("-10**400", "gives -inf"),
    ("1/x", "gives inf, not a finite number at 1 of 4 points, first at x = 0, y = 1 (a division"),
    ("log(x - 1.5)", "gives nan, not a finite number at 2 of 4 points, first at x = 0, y = 1 (0/0"),
    ("1/(t - 2)", "gives inf, not a finite number at 4 of 4 points, first at x = 0, y = 1, t = 2"),
    ("-(x < 1)", "cannot be evaluated: The numpy boolean negative"),
])
def test_values_that_are_not_finite_are_errors_at_once(source, words):
    """Floating-point errors give inf or nan (numpy's rules, at once: 10**10**10 is not a big integer, or it
    would not give inf); a result that is not finite is an error naming the value and the first point that
    gives it."""
    with pytest.raises(ExpressionError) as err:
        Expression(source)(X, Y, 2.0)
    assert words in str(err.value)


def test_infinities_that_where_discards_are_fine():
    assert np.array_equal(Expression("where(x > 0, 1/x, 0)")(X, Y), [0.0, 1.0, 0.5, 0.2])


def test_a_speed_law_names_the_density():
    with pytest.raises(ExpressionError, match="gives inf, not a finite number at 1 of 3 points, first at rho = 0.5"):
        Expression("1 / (rho - 0.5)", variables=("rho",)).of(rho=np.array([0.0, 0.5, 1.0]))


@pytest.mark.parametrize("source, words", [
    ("1" * 400, "beyond the range of floats"), ("1e400", "beyond the range of floats"),
    ("x + " * 5000 + "x", f"is 20001 characters long: an expression may have at most {MAX_LENGTH}"),
    ("not " * 50000 + "x", "is 200001 characters long"),
    ("+".join(["x"] * 200000), "is 399999 characters long"),
    ("-" * 5000 + "x", f"is nested too deeply: an expression may be at most {MAX_DEPTH} levels deep"),
    ("x**" * 3000 + "x", "is nested too deeply"),   # the parser itself runs out of memory
    ("+".join(["x"] * 200), "is nested too deeply"),
    ("(" * 199 + "x" + ")" * 199 + " + " + "-" * 250 + "x", "is nested too deeply"),
    (balanced_sum(1024), f"is too long: an expression may have at most {MAX_NODES} nodes"),
    ("sqrt(x, y)", "sqrt() takes 1 argument, not 2"), ("sqrt()", "sqrt() takes 1 argument, not 0"),
    ("where(x > 1)", "where() takes 3 arguments, not 1"), ("hypot(x)", "hypot() takes 2 arguments, not 1"),
    ("clip(x, 0)", "clip() takes 3 arguments, not 2"),
])
def test_limits_and_arities_are_checked_before_evaluation(source, words):
    """Too long, too deep, too many nodes, a number beyond floats, a wrong number of arguments: refused when
    parsed (by the constructor, before any evaluation), never a RecursionError or MemoryError."""
    with pytest.raises(ExpressionError) as err:
        Expression(source)
    assert words in str(err.value)


def test_expressions_within_the_limits_are_evaluated():
    assert np.array_equal(Expression("+".join(["x"] * 199))(X, Y), 199 * X)
    assert np.array_equal(Expression(balanced_sum(512))(X, Y), 512 * X)
    assert np.array_equal(Expression("(" * 150 + "x" + ")" * 150)(X, Y), X)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_each_function_takes_its_own_number_of_arguments(name):
    """With its number of arguments a function is evaluated; with one more it is refused (a ufunc would take the
    extra one as its `out` array and write into x)."""
    x = X.copy()
    args = ", ".join(["x / 10 + 0.1"] * ARITY[name])
    assert Expression(f"{name}({args})")(x, Y).shape == X.shape
    with pytest.raises(ExpressionError, match=rf"{name}\(\) takes {ARITY[name]} argument"):
        Expression(f"{name}({args}, x)")
    assert np.array_equal(x, X)


def test_an_expression_of_a_case_key_raises_an_input_error_naming_it():
    expression = Expression("1 / (x - 1)", origin=("case.toml", "initial.density"))
    with pytest.raises(InputError, match=r"^case.toml: initial.density = '1 / \(x - 1\)': gives inf, not a finite"):
        expression(X, Y)
    with pytest.raises(InputError, match=r"^case.toml: velocity.ux = 'sqrt\(x, y\)': sqrt\(\) takes 1 argument"):
        Expression("sqrt(x, y)", origin=("case.toml", "velocity.ux"))
