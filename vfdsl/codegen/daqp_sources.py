"""The DAQP C sources that every generated tick is compiled against, and their static library.

The generated C calls DAQP (Arnström, Bemporad & Axehill; MIT licence) directly: its hierarchical mode (priority
levels in one solve) and its warm-started updates are in the C sources of the ``daqp`` package, not in the older
copy that CasADi bundles. PyPI's ``daqp`` wheels hold only the compiled Python module, so the sources come from the
package's source distribution, of exactly the installed version (the interpreted path solves with that module:
both paths run the same solver):

    <cache_dir>/daqp-<version>/
        LICENSE            DAQP's licence (shipped with every export)
        include/daqp/*.h   the headers (generated code includes <daqp/api.h>)
        src/*.c            the sources

The source distribution is fetched once with ``pip download --no-binary daqp`` (so a configured index or mirror is
used; only daqp itself as source: ``--no-binary :all:`` would also build daqp's build requirements, Cython among
them, from source to prepare its metadata, minutes on a small machine) and checked against its recorded sha256;
``VFDSL_DAQP_SDIST`` may name an already downloaded ``daqp-<version>.tar.gz``. Fetching, and building the solver
library after it, each say so in one line on stderr (:func:`announce`): the first controller on a machine is the
only one that waits for them.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

from vfdsl.errors import VfError

SDIST_SHA256 = {"0.11.0": "2f27baf18d2acca14186498e651b34e0bed455627e777d3fd8ba655e7e40f920"}
"""The source distributions this vfdsl is tested with (their sha256 as published on PyPI)."""


class DaqpSourcesUnavailable(VfError):
    """DAQP's C sources could not be fetched or do not match the recorded checksum."""


def daqp_version() -> str:
    """The installed ``daqp`` package's version (the interpreted path's solver)."""
    try:
        return importlib.metadata.version("daqp")
    except importlib.metadata.PackageNotFoundError:
        raise DaqpSourcesUnavailable("the daqp package is not installed",
                                     hint="pip install 'daqp==0.11.0'") from None


def announce(action: str) -> None:
    """One line on stderr for work done once per machine that takes more than a moment."""
    print(f"vfdsl: {action} (once) ...", file=sys.stderr, flush=True)


def pip_download(version: str) -> list[str]:
    """The pip command that downloads DAQP ``version``'s source distribution (only it: no dependency, and no build
    requirement built from source)."""
    return ["pip", "download", "--no-deps", "--no-binary", "daqp", f"daqp=={version}"]


def daqp_sources(cache_dir: Path) -> Path:
    """The directory holding DAQP's ``LICENSE``, ``include/daqp/`` and ``src/`` for the installed version,
    fetched into ``cache_dir`` on first use."""
    version = daqp_version()
    if version not in SDIST_SHA256:
        raise DaqpSourcesUnavailable(f"daqp {version} is installed; this vfdsl generates code for daqp "
                                     f"{', '.join(SDIST_SHA256)}",
                                     hint=f"pip install 'daqp=={next(iter(SDIST_SHA256))}'")
    root = Path(cache_dir) / f"daqp-{version}"
    if (root / "LICENSE").is_file() and (root / "src").is_dir() and (root / "include" / "daqp" / "api.h").is_file():
        return root
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=cache_dir, prefix=".daqp-") as tmp:
        sdist = _sdist(version, Path(tmp))
        staged = Path(tmp) / "staged"
        _unpack(sdist, version, staged)
        try:
            os.replace(staged, root)
        except OSError:          # another process published it first
            if not (root / "LICENSE").is_file():
                raise
    return root


def _sdist(version: str, tmp: Path) -> Path:
    """The verified ``daqp-<version>.tar.gz``: ``VFDSL_DAQP_SDIST``, else downloaded with pip."""
    given = os.environ.get("VFDSL_DAQP_SDIST")
    if given:
        path = Path(given)
    else:
        announce(f"fetching DAQP {version}'s C sources with pip")
        argv = [sys.executable, "-m", *pip_download(version), "-d", str(tmp), "--disable-pip-version-check", "-q"]
        result = subprocess.run(argv, capture_output=True, text=True)
        found = sorted(tmp.glob(f"daqp-{version}.tar.gz"))
        if not found:
            raise DaqpSourcesUnavailable(
                f"cannot download DAQP {version}'s C sources (its source distribution from the package index): "
                f"{((result.stderr or result.stdout).strip().splitlines() or ['no file'])[-1]}",
                hint=f"run `{' '.join(pip_download(version))}` where the index is reachable and set "
                     "VFDSL_DAQP_SDIST to the .tar.gz")
        path = found[0]
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise DaqpSourcesUnavailable(f"cannot read {path}: {exc.strerror}") from None
    if digest != SDIST_SHA256[version]:
        raise DaqpSourcesUnavailable(f"{path} is not DAQP {version}'s source distribution (sha256 {digest[:16]}..., "
                                     f"expected {SDIST_SHA256[version][:16]}...)")
    return path


def _unpack(sdist: Path, version: str, staged: Path) -> None:
    """LICENSE, csrc/include/*.h (as include/daqp/) and csrc/src/*.c of the archive into ``staged``."""
    top = f"daqp-{version}/"
    wanted = {f"{top}LICENSE": Path("LICENSE")}
    with tarfile.open(sdist, "r:gz") as archive:
        for member in archive.getmembers():
            name = member.name
            if not member.isfile():
                continue
            if name.startswith(f"{top}csrc/include/") and name.endswith(".h") and name.count("/") == 3:
                wanted[name] = Path("include", "daqp", Path(name).name)
            elif name.startswith(f"{top}csrc/src/") and name.endswith(".c") and name.count("/") == 3:
                wanted[name] = Path("src", Path(name).name)
        for name, target in wanted.items():
            source = archive.extractfile(name)
            if source is None:
                raise DaqpSourcesUnavailable(f"{sdist} lacks {name}")
            (staged / target).parent.mkdir(parents=True, exist_ok=True)
            with source, open(staged / target, "wb") as out:
                shutil.copyfileobj(source, out)
    if not (staged / "include" / "daqp" / "api.h").is_file() or not any((staged / "src").glob("*.c")):
        raise DaqpSourcesUnavailable(f"{sdist} does not hold DAQP's C sources where expected")


def source_files(root: Path) -> list[Path]:
    """DAQP's C files, in a fixed order."""
    return sorted((root / "src").glob("*.c"))
