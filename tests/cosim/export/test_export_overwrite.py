"""An export replaces only what an earlier export wrote, unchanged since: an OSP folder of
a user's own (their XML, their ``MyController.fmu``), an earlier export folder with a file
changed or added, and a user-modified copy of an exported SSP archive are refused in one
line and left byte for byte (an archive with ``--force`` only)."""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim import cli
from cosim.errors import CosimError
from cosim.export import OSP_FILE, export_osp, export_ssp
from cosim.scenario.spec import Scenario, load_scenario

PLANT_ALONE = """\
id = "plant-alone"
stop_time = 2.0
[coupling]
step = 0.01
[instances.plant]
fmu = "{fmu}"
[instances.plant.start]
variant = 1
"""


@pytest.fixture(scope="module")
def plant_alone(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Scenario:
    path = tmp_path_factory.mktemp("scenario") / "plant-alone.toml"
    path.write_text(PLANT_ALONE.format(fmu=fmu_paths["AuvPlant"]))
    return load_scenario(path)


def tree(folder: Path) -> dict[str, bytes | str]:
    """Every entry below ``folder`` -> its bytes (a link: where it points)."""
    return {
        str(p.relative_to(folder)): os.readlink(p) if p.is_symlink() else p.read_bytes()
        for p in sorted(folder.rglob("*"))
    }


def a_users_own_osp_folder(folder: Path, scenario: Scenario) -> None:
    folder.mkdir()
    (folder / OSP_FILE).write_text("<OspSystemStructure><!-- mine --></OspSystemStructure>\n")
    (folder / "MyController.fmu").write_bytes(b"my controller\n")
    (folder / "AuvPlant.fmu").write_bytes(scenario.instances["plant"].fmu_path.read_bytes())


def an_export_with_its_fmu_replaced(folder: Path, scenario: Scenario) -> None:
    export_osp(scenario, folder)
    (folder / "AuvPlant.fmu").write_bytes(b"my own build\n")


def an_export_with_its_xml_edited(folder: Path, scenario: Scenario) -> None:
    export_osp(scenario, folder)
    xml = folder / OSP_FILE
    xml.write_text(xml.read_text().replace("<!--", "<!-- my note -->\n<!--", 1))


def an_export_with_a_users_fmu_added(folder: Path, scenario: Scenario) -> None:
    export_osp(scenario, folder)
    (folder / "MyController.fmu").write_bytes(b"my controller\n")


def an_export_with_a_link_added(folder: Path, scenario: Scenario) -> None:
    export_osp(scenario, folder)
    (folder / "Other.fmu").symlink_to(folder / "AuvPlant.fmu")


OSP_CASES: list[Callable[[Path, Scenario], None]] = [
    a_users_own_osp_folder,
    an_export_with_its_fmu_replaced,
    an_export_with_its_xml_edited,
    an_export_with_a_users_fmu_added,
    an_export_with_a_link_added,
]


@pytest.mark.parametrize("make", OSP_CASES, ids=lambda f: f.__name__)
def test_an_osp_export_replaces_only_an_unchanged_earlier_export(
    plant_alone: Scenario, tmp_path: Path, make: Callable[[Path, Scenario], None]
) -> None:
    """`export --osp` into a folder of a user's own OSP files removed their
    MyController.fmu and replaced their XML."""
    folder = tmp_path / "osp"
    make(folder, plant_alone)
    before = tree(folder)
    with pytest.raises(CosimError, match=r"^cannot write .*(not a file an export wrote|no record)"):
        export_osp(plant_alone, folder)
    assert tree(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["osp"]  # no temporaries left


def test_an_unchanged_earlier_osp_export_is_replaced(plant_alone: Scenario, tmp_path: Path):
    folder = tmp_path / "osp"
    export_osp(plant_alone, folder)
    first = tree(folder)
    (folder / OSP_FILE).touch()  # the time alone changes nothing
    export_osp(plant_alone, folder)
    assert tree(folder) == first


def rewrite(archive: Path, change: Callable[[str, bytes], bytes | None], add: bool = False) -> None:
    """Rewrite the zip ``archive`` member by member (``change`` returns the new bytes, or
    None to keep them), keeping its comment, as a zip tool would."""
    with zipfile.ZipFile(archive) as src:
        members = [(info, src.read(info)) for info in src.infolist()]
        comment = src.comment
    with zipfile.ZipFile(archive, "w") as dst:
        for info, data in members:
            dst.writestr(info, change(info.filename, data) or data)
        if add:
            dst.writestr("resources/MyController.fmu", b"my controller\n")
        dst.comment = comment


SSP_CHANGES: dict[str, Callable[[Path], None]] = {
    "a parameter edited in the SSD": lambda a: rewrite(
        a, lambda n, d: d.replace(b'value="1"', b'value="2"', 1) if n.endswith(".ssd") else None
    ),
    "its FMU replaced": lambda a: rewrite(
        a, lambda n, d: b"my own build\n" if n.endswith(".fmu") else None
    ),
    "a member added": lambda a: rewrite(a, lambda n, d: None, add=True),
}


@pytest.mark.parametrize("change", list(SSP_CHANGES))
def test_a_changed_copy_of_an_exported_archive_needs_force(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture[str], change: str
) -> None:
    """`export --ssp` replaced a user-modified copy of an exported archive without
    --force (it only looked for the generator's name in the SSD)."""
    archive = export_ssp(plant_alone, tmp_path / "p.ssp")
    SSP_CHANGES[change](archive)
    before = archive.read_bytes()
    command = ["export", str(plant_alone.source), "--ssp", str(archive)]
    capsys.readouterr()
    assert cli.main(command) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not an archive auv-cosim export wrote" in err, err
    assert archive.read_bytes() == before
    assert cli.main([*command, "--force"]) == 0
    assert archive.read_bytes() != before


def test_an_unchanged_exported_archive_is_replaced(plant_alone: Scenario, tmp_path: Path):
    archive = export_ssp(plant_alone, tmp_path / "p.ssp")
    first = archive.read_bytes()
    archive.touch()
    assert export_ssp(plant_alone, archive).read_bytes() == first
