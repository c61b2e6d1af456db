"""A downstream user's mistakes, each a ``mypy --strict`` error at its line (``# error:``
and the start of mypy's message): tests/cosim/test_api_typing.py checks that each is one.
It is type-checked only, never run."""

import cosim


def mistakes() -> None:
    """Misspelt names and options the type checker, not the run, catches."""
    cosim.rnu("bs-3")  # error: Module has no attribute "rnu"
    # (run is overloaded on out=: mypy's notes list each variant, with the choices)
    cosim.run("bs-3", algorithm="gauss_seidel")  # error: No overload variant of "run" matches
    cosim.run("bs-3", extrapolation="cubic")  # error: No overload variant of "run" matches
    scenario = cosim.load_scenario("bs-3")
    scenario.with_overrides(error_estimate="doubled")  # error: Argument "error_estimate"
    major: int = cosim.__version__  # error: Incompatible types in assignment
    print(major)
