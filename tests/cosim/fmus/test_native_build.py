"""Which loaders a build compiles: linux64 always, win64 only when asked for, because
zig's first cross-compile on a machine takes minutes that a first `auv-cosim run` should
not pay."""

from __future__ import annotations

import pytest

from cosim.fmus import native


@pytest.mark.parametrize(("flag", "platforms"), [(None, ["linux64"]), ("1", ["linux64", "win64"])])
def test_the_win64_loader_is_compiled_only_when_asked_for(
    monkeypatch: pytest.MonkeyPatch, flag: str | None, platforms: list[str]
) -> None:
    if flag is None:
        monkeypatch.delenv("AUV_FMU_WIN64", raising=False)
    else:
        monkeypatch.setenv("AUV_FMU_WIN64", flag)
    zig = native.Toolchain("zig", ("zig", "cc"), cross=True)
    monkeypatch.setattr(native, "toolchain", lambda: zig)
    compiled: list[str] = []
    monkeypatch.setattr(
        native, "_compiled", lambda chain, platform: compiled.append(platform) or b"lib"
    )
    monkeypatch.setattr(native, "_rewrite", lambda fmu, name, loaders: None)
    assert native.install_loader(None, "AuvPlant") == []  # type: ignore[arg-type]
    assert compiled == platforms
