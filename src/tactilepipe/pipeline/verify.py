"""Re-hash the workspace against what DVC recorded (dvc.lock and the .dvc files), file by file.

DVC trusts its cache: `dvc pull` and `dvc checkout` copy an object without hashing it again, and
`dvc status` skips a file whose size and time it has seen before. An object corrupted in the cache
(and the remote) therefore reaches the workspace with a clean status. This reads every file DVC
tracks, directories expanded through their manifests, and compares its md5 with the record.
"""

from __future__ import annotations

from pathlib import Path

from tactilepipe.core.hashing import file_digest


def verify_workspace(root: str | Path = ".") -> tuple[int, list[str]]:
    """(files checked, problems): each problem names a tracked file that is missing or whose
    content differs from its record."""
    from dvc.repo import Repo
    root = Path(root)
    checked, problems = 0, []
    with Repo(str(root)) as repo:
        try:
            entries = list(repo.index.data["repo"].iteritems())
        except Exception as exc:  # noqa: BLE001  (dvc_data's DataIndexDirError and kin: a manifest it cannot read)
            return 0, [f"cannot list the tracked files: {type(exc).__name__}: {str(exc).splitlines()[0]} (a directory's "
                       f"manifest is missing or corrupt in the cache: `dvc fetch` restores it from the remote)"]
        for key, entry in entries:
            if entry.meta is not None and entry.meta.isdir:
                continue
            recorded = entry.hash_info
            if recorded is None or recorded.name != "md5" or not recorded.value:
                continue
            path = root.joinpath(*key)
            checked += 1
            if not path.is_file():
                problems.append(f"{path.relative_to(root)}: missing (recorded md5 {recorded.value})")
                continue
            actual = file_digest(path, "md5")
            if actual != recorded.value:
                problems.append(f"{path.relative_to(root)}: content md5 {actual}, recorded {recorded.value}")
    return checked, problems
