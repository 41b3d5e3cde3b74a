#!/usr/bin/env python3
"""Fetch the ONNX Runtime shared library that `tre` loads at run time.

The library comes from the official `onnxruntime` wheel on PyPI: the wheel is downloaded
with pip (no dependencies, binary only), and `libonnxruntime.so.VERSION` plus
`libonnxruntime_providers_shared.so` are extracted into DEST, next to a `libonnxruntime.so`
link. Nothing is installed into any Python environment. Running it again is a no-op.

    python3 scripts/fetch_onnxruntime.py [--dest DIR] [--version 1.31.1]

On success the absolute path of the library is the only line printed on stdout; point
`ORT_DYLIB_PATH` at it to use it from anywhere. Standard library only.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

DEFAULT_VERSION = "1.31.1"
REPO_ROOT = Path(__file__).resolve().parent.parent
WHEEL_DIR = "onnxruntime/capi/"


class FetchError(Exception):
    """A failure with a message that says what went wrong and what to do."""


def library_names(version: str) -> list[str]:
    """The files taken from the wheel: the versioned runtime first."""
    return [f"libonnxruntime.so.{version}", "libonnxruntime_providers_shared.so"]


def default_dest(version: str) -> Path:
    """`<repo>/.ort/onnxruntime-VERSION/`, where the build looks for it."""
    return REPO_ROOT / ".ort" / f"onnxruntime-{version}"


def download_wheel(version: str, tmp: Path) -> Path:
    """Download the onnxruntime wheel for this platform into `tmp` with pip."""
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "download",
        "--no-deps",
        "--only-binary=:all:",
        "--disable-pip-version-check",
        "--quiet",
        f"onnxruntime=={version}",
        "-d",
        str(tmp),
    ]
    # pip's own progress and errors go to stderr so that stdout carries only the path.
    result = subprocess.run(cmd, stdout=sys.stderr, stderr=sys.stderr, check=False)
    if result.returncode != 0:
        raise FetchError(
            f"`{' '.join(cmd)}` failed with exit status {result.returncode}; check that pip "
            f"can reach PyPI and that onnxruntime {version} has a wheel for this platform"
        )
    wheels = sorted(tmp.glob(f"onnxruntime-{version}-*.whl"))
    if not wheels:
        raise FetchError(f"pip succeeded but left no onnxruntime-{version} wheel in {tmp}")
    return wheels[0]


def extract(wheel: Path, version: str, staging: Path) -> None:
    """Copy the runtime libraries out of `wheel` into `staging`, executable."""
    with zipfile.ZipFile(wheel) as archive:
        members = set(archive.namelist())
        for name in library_names(version):
            member = WHEEL_DIR + name
            if member not in members:
                raise FetchError(f"{wheel.name} has no {member}; is {version} the right version?")
            target = staging / name
            with archive.open(member) as src, open(target, "wb") as dst:
                shutil.copyfileobj(src, dst)
            target.chmod(0o755)
    link = staging / "libonnxruntime.so"
    try:
        link.symlink_to(library_names(version)[0])
    except OSError:
        shutil.copy2(staging / library_names(version)[0], link)


def fetch(dest: Path, version: str) -> Path:
    """Make sure DEST holds the runtime and return the library's path."""
    library = dest / library_names(version)[0]
    if library.is_file():
        return library
    if dest.exists():
        raise FetchError(f"{dest} exists but holds no {library.name}; remove it and run again")
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".ort-fetch-", dir=dest.parent) as tmp:
        wheel = download_wheel(version, Path(tmp))
        staging = Path(tmp) / "staging"
        staging.mkdir()
        extract(wheel, version, staging)
        # Publish with one rename so a concurrent build never sees half a directory.
        try:
            staging.rename(dest)
        except OSError:
            if not library.is_file():
                raise
    return library


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, fetch, print the library's path."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--version", default=DEFAULT_VERSION, help="onnxruntime version")
    parser.add_argument(
        "--dest", type=Path, help="target folder (default: .ort/onnxruntime-VERSION)"
    )
    args = parser.parse_args(argv)
    dest = (args.dest or default_dest(args.version)).resolve()
    try:
        library = fetch(dest, args.version)
    except (FetchError, OSError, zipfile.BadZipFile) as err:
        print(f"fetch_onnxruntime: error: {err}", file=sys.stderr)
        print(
            f"fetch_onnxruntime: alternatively `pip install onnxruntime=={args.version}` and set "
            f"ORT_DYLIB_PATH=<site-packages>/onnxruntime/capi/libonnxruntime.so.{args.version}",
            file=sys.stderr,
        )
        return 1
    print(library)
    return 0


if __name__ == "__main__":
    sys.exit(main())
