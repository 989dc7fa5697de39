"""Study 000's published archives (data_normal.zip, data_shear.zip) -> a public-layout session.

``verify`` checks a downloaded file against the size and sha256 of the study's Git LFS pointer
(params.yaml public_data.files); ``unpack`` extracts an archive's trials into
``<session>/data_normal/<trial>/{tactile1,tactile2,force}/`` (the layout tool/formats/public_layout.py
reads), atomically (into a temporary folder beside it, then renamed) and refusing members that
would land outside it; ``write_trials_template`` lists every trial in the session's trials.csv
with an empty tool and pose for the user to fill in (rows already there are kept as they are).

Inside the archive a trial is any folder holding tactile1/, tactile2/ or force/, at whatever
depth (the archive may or may not wrap its trials in a data_normal/ folder); other members
(macOS resource forks, notes) are skipped.
"""

from __future__ import annotations

import shutil
import stat
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

from tactilepipe.core.atomic import write_text
from tactilepipe.core.csvtext import read_text_table
from tactilepipe.core.errors import InputError, TactilepipeError
from tactilepipe.core.hashing import file_sha256
from tactilepipe.tool.formats.trials import PUBLIC_KINDS, TRIALS_CSV, TRIALS_HEADER
from tactilepipe.tool.formats.public_layout import FORCE_DIR, SENSOR_DIRS

TRIAL_PARTS = set(SENSOR_DIRS) | {FORCE_DIR}
CHUNK = 1 << 20


def verify_listed(path: str | Path, files: dict, name: str, option: str) -> None:
    """``verify`` against the entry ``name`` of params.yaml public_data.files (``files``);
    ``option`` is the command-line option that named it, for the error."""
    if name not in files:
        raise TactilepipeError(f"{option} {name}: not a file of params.yaml public_data.files ({sorted(files)})")
    verify(path, files[name]["size"], files[name]["sha256"])


def verify(path: str | Path, size: int, sha256: str) -> None:
    """InputError naming ``path`` unless it has exactly ``size`` bytes and this sha256."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "missing: import it first (docs/reproduce_study_000.md)")
    actual = path.stat().st_size
    if actual != size:
        raise InputError(path, f"size {actual:,} bytes, expected {size:,} (params.yaml public_data.files): "
                               f"an incomplete or different download, refused")
    digest = file_sha256(path)
    if digest != sha256:
        raise InputError(path, f"sha256 {digest} differs from the expected {sha256} (params.yaml "
                               f"public_data.files): a corrupted or different file, refused")


def _member_target(info: zipfile.ZipInfo, archive: Path) -> tuple[str, str, PurePosixPath] | None:
    """(trial name, trial folder in the archive, path inside the trial) of a member, None for
    members that are not trial data."""
    name = info.filename.replace("\\", "/")
    parts = PurePosixPath(name).parts
    if name.startswith("/") or (parts and parts[0].endswith(":")) or ".." in parts:
        raise InputError(archive, f"member {info.filename!r} would be written outside the session folder: refused")
    if stat.S_ISLNK(info.external_attr >> 16):
        raise InputError(archive, f"member {info.filename!r} is a symbolic link: refused")
    if "__MACOSX" in parts or any(p.startswith(".") for p in parts) or info.is_dir():
        return None
    cut = next((i for i, p in enumerate(parts) if p in TRIAL_PARTS), None)
    if cut is None or cut == 0 or cut == len(parts) - 1:
        return None
    return parts[cut - 1], "/".join(parts[:cut]), PurePosixPath(*parts[cut:])


def unpack(archive: str | Path, kind_dir: str, session_dir: str | Path) -> list[str]:
    """Extract ``archive``'s trials into ``session_dir/kind_dir/`` (replacing that folder
    atomically); returns the trial names."""
    archive, session_dir = Path(archive), Path(session_dir)
    if kind_dir not in PUBLIC_KINDS:
        raise InputError(archive, f"unknown archive kind '{kind_dir}' (one of {sorted(PUBLIC_KINDS)})")
    if not zipfile.is_zipfile(archive):
        raise InputError(archive, "not a zip archive")
    session_dir.mkdir(parents=True, exist_ok=True)
    target = session_dir / kind_dir
    tmp = Path(tempfile.mkdtemp(prefix=f".{kind_dir}.", dir=session_dir))
    try:
        sources: dict[str, str] = {}
        with zipfile.ZipFile(archive) as zf:
            for info in zf.infolist():
                found = _member_target(info, archive)
                if found is None:
                    continue
                trial, where, inner = found
                if sources.setdefault(trial, where) != where:
                    raise InputError(archive, f"trial name '{trial}' is used by two folders "
                                              f"({sources[trial]} and {where})")
                dest = (tmp / trial / inner).resolve()
                if tmp.resolve() not in dest.parents:
                    raise InputError(archive, f"member {info.filename!r} would be written outside the "
                                              f"session folder: refused")
                dest.parent.mkdir(parents=True, exist_ok=True)
                with zf.open(info) as src, open(dest, "wb") as out:
                    shutil.copyfileobj(src, out, CHUNK)
        if not sources:
            raise InputError(archive, "no trials found (folders holding tactile1/, tactile2/ and force/)")
        old = None
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{kind_dir}.old.", dir=session_dir))
            target.rename(old / kind_dir)
        tmp.rename(target)
        if old is not None:
            shutil.rmtree(old)
        return sorted(sources)
    except zipfile.BadZipFile as exc:
        raise InputError(archive, f"damaged zip archive ({exc})") from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)


def write_trials_template(session_dir: str | Path) -> list[str]:
    """Add a row (trial named kind_dir/trial, empty tool and pose) to the session's trials.csv for
    every public trial it does not list yet; rows already there, completed or not, are kept.
    Returns the trials added."""
    session_dir = Path(session_dir)
    path = session_dir / TRIALS_CSV
    trials = [f"{k}/{t.name}" for k in sorted(PUBLIC_KINDS) if (session_dir / k).is_dir()
              for t in sorted((session_dir / k).iterdir()) if t.is_dir() and not t.name.startswith(".")]
    text = read_text_table(path, TRIALS_CSV) if path.exists() else ",".join(TRIALS_HEADER) + "\n"
    listed = {line.split(",", 1)[0].strip() for line in text.splitlines()[1:] if line.strip()}
    added = [t for t in trials if t not in listed and t.split("/", 1)[1] not in listed]
    if added or not path.exists():
        body = text if text.endswith("\n") else text + "\n"
        write_text(path, body + "".join(f"{t},,,\n" for t in added))
    return added
