"""Regenerate the prebuilt win64 runtime: ``fmu_runtime/native/prebuilt/win64/runtime.dll``
and its record ``built_from.txt`` (the SHA-256 of the C sources, headers and flags it was
built from, the DLL's own SHA-256, the zig version and the command).

The FMU build puts that DLL in every FMU as ``binaries/win64/<id>.dll`` while the record's
``sources_sha256`` is today's (``cosim.fmus.native.win64_sources_digest``): run this after
editing anything in ``fmu_runtime/native/``, and commit both files. It needs the
``ziglang`` package (``pip install "auv-cosim[zig]"``); zig's first cross-compile on a
machine takes about two minutes (it builds its MinGW libraries once), later ones seconds.
zig's output is byte-reproducible (same zig version, any folder): ``--out DIR`` writes the
two files to DIR instead, to compare.

Usage: ``python scripts/build_win64_runtime.py [--out DIR]``.
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.fmus import native

HEADER = (
    "# The win64 runtime beside this file, cross-compiled by scripts/build_win64_runtime.py.\n"
    "# The FMU build uses it while sources_sha256 is cosim.fmus.native.win64_sources_digest().\n"
)


def zig_version(zig: native.Toolchain) -> str:
    """``zig version`` of the ziglang package, e.g. ``0.17.1``."""
    command = [*zig.command[:-1], "version"]  # python -m ziglang version
    return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()


def build(out_dir: Path) -> Path:
    """Compile the win64 runtime and write it with its record into ``out_dir``; return the
    DLL's path. Raises SystemExit without ziglang or when the compile fails."""
    zig = native.zig()
    if zig is None:
        raise SystemExit('no ziglang package: pip install "auv-cosim[zig]"')
    with tempfile.TemporaryDirectory(prefix="win64_runtime_") as tmp:
        out = Path(tmp) / native.PREBUILT_DLL.name
        command = native.compile_command(zig, out, "-Werror", platform="win64")
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"the win64 runtime did not compile:\n{done.stderr[-3000:]}")
        dll = out.read_bytes()
    shown = native.compile_command(zig, Path(native.PREBUILT_DLL.name), platform="win64")
    flags = shown[len(zig.command) : shown.index("-o")]
    record = HEADER + "".join(
        f"{key}={value}\n"
        for key, value in (
            ("sources_sha256", native.win64_sources_digest()),
            ("dll_sha256", hashlib.sha256(dll).hexdigest()),
            ("zig", zig_version(zig)),
            ("command", " ".join(["zig", "cc", *flags])),
        )
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / native.PREBUILT_DLL.name).write_bytes(dll)
    (out_dir / native.PREBUILT_RECORD.name).write_text(record, encoding="utf-8")
    return out_dir / native.PREBUILT_DLL.name


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=native.PREBUILT_DIR, help="folder")
    args = parser.parse_args(argv)
    dll = build(args.out)
    print(f"{dll} ({dll.stat().st_size} bytes)", file=sys.stderr)


if __name__ == "__main__":
    main()
