"""The renaming of the FMU's imports into its build package (cosim/fmus/staging.py): every
form of absolute import of a shipped package, nothing else, every line where it was."""

from __future__ import annotations

import pytest

from cosim.errors import CosimError
from cosim.fmus import staging

NAMES = frozenset({"plant_fmu", "pythonfmu"})
P = "auvfmu_0123456789ab"


@pytest.mark.parametrize(
    "template",  # {p} marks where the package goes, {a} an "as" the renaming adds
    [
        "from {p}plant_fmu.model import x\n",
        "from {p}plant_fmu import (\n    a,\n    b,\n)\n",
        "import {p}plant_fmu{a}\n",
        "import {p}plant_fmu.model as m\n",
        "import os, {p}plant_fmu as p\n",
        "if x:\n    from {p}pythonfmu.enums import E\n",
        "a = 1; from {p}plant_fmu import b\n",
        "importlib.import_module('{p}plant_fmu.model')\n",
        '__import__("{p}pythonfmu")\n',
    ],
)
def test_every_form_of_absolute_import_is_renamed(template):
    source = template.format(p="", a="")
    renamed = template.format(p=f"{P}.", a=" as plant_fmu")
    assert staging.rename_imports(source, P, NAMES, "m.py") == renamed


@pytest.mark.parametrize(
    "source",
    [
        "from . import plant_fmu\n",  # relative: already inside the package
        "from .plant_fmu import x\n",
        "import numpy\nfrom numpy import plant_fmu\n",  # another package's member
        '"""plant_fmu.model.x is documented here"""\n',  # a string is not an import
        "# from plant_fmu import x\n",
        "name = 'plant_fmu'\n",  # a string not passed to an import function
        "raise ValueError('x') from plant_fmu\n",  # `from` inside a statement
        "from plant_fmu_extra import x\n",  # another top-level package
    ],
)
def test_nothing_else_is_touched(source):
    assert staging.rename_imports(source, P, NAMES, "m.py") == source


def test_a_dotted_import_without_as_is_refused_with_the_file_and_line():
    with pytest.raises(CosimError, match=r"m\.py:2: `import plant_fmu\.model` cannot be renamed"):
        staging.rename_imports("import os\nimport plant_fmu.model\n", P, NAMES, "m.py")


def test_the_package_name_is_a_function_of_the_content():
    files = {"pkg/a.py": b"x = 1\n", "pkg/b.toml": b"m = 1\n"}
    name = staging.package_name(files)
    assert name.startswith("auvfmu_") and len(name) == len("auvfmu_") + 12
    assert staging.package_name(dict(reversed(list(files.items())))) == name
    assert staging.package_name({**files, "pkg/b.toml": b"m = 2\n"}) != name
    assert staging.package_name({"pkg/c.py": b"x = 1\n", "pkg/b.toml": b"m = 1\n"}) != name
