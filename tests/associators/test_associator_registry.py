"""The associator registry is lazy, as the track registry is: a built-in's module is imported when
that method is asked for, so a run imports (and its stored inputs name) its own method's modules
and no other method's."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from assocbench.associators.registry import ALL_BUILTINS, builtin_class, names

LOADED = "print(sorted(m for m in sys.modules if m.startswith('assocbench.associators.')))"


def _associator_modules(code: str) -> set[str]:
    """The ``assocbench.associators.*`` modules a fresh interpreter has loaded after ``code``."""
    out = subprocess.run([sys.executable, "-c", f"import sys\n{code}\n{LOADED}"], capture_output=True, text=True,
                         timeout=120, check=True)
    return {m.removeprefix("assocbench.associators.") for m in ast.literal_eval(out.stdout.strip().splitlines()[-1])}


@pytest.mark.parametrize(("asked", "loaded"), [
    ("mnn", {"base", "registry", "mnn"}),
    ("jcbb", {"base", "registry", "jcbb", "lsa", "rjc", "rjc_kernels", "anytime_search", "jcbb_dive", "jcbb_quick",
              "jcbb_search"}),   # jcbb.py imports LSA and RJC itself
    ("kdtree", {"base", "registry", "dense", "dense.base", "dense.kdtree"}),
])
def test_making_a_built_in_imports_its_own_modules_and_no_other_methods(asked, loaded):
    assert _associator_modules(f"from assocbench import make_associator\nmake_associator({asked!r})") == loaded


def test_listing_the_names_imports_no_method():
    """``names`` (and an unknown name's error, which lists them) imports no built-in; ``available``
    needs each summary, so it imports them all."""
    code = ("from assocbench import UserError, make_associator\nfrom assocbench.associators.registry import names\n"
            "assert 'jcbb' in names() and 'kdtree' in names()\n"
            "try:\n    make_associator('jcbbb')\nexcept UserError as exc:\n    assert 'did you mean jcbb' in str(exc)")
    assert _associator_modules(code) == {"base", "registry"}


def test_every_built_in_name_is_its_class_name():
    assert names()[:len(ALL_BUILTINS)] == list(ALL_BUILTINS)
    for name, spec in ALL_BUILTINS.items():
        cls = builtin_class(name)
        assert (cls.name, f"{cls.__module__}:{cls.__qualname__}") == (name, spec)
