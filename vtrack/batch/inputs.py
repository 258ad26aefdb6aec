"""Which videos a batch processes, and the name of each one's output folder.

Inputs are files, folders (scanned recursively for video files by extension) and glob
patterns (``**`` recursive). Every input must yield at least one video. Hidden files and
folders (name starting with ".") are not scanned, nor is the batch's own output folder
(it holds annotated.mp4 files from earlier runs). A file reached twice is processed once.

Output names: a video's stem, unless several videos share it; then each of those gets the
shortest run of its parent folders' names that tells them apart as a prefix
(``cam1/0800.mp4``, ``cam2/0800.mp4`` -> ``cam1_0800``, ``cam2_0800``; same folder, other
extension -> ``..._0800_avi``). Deterministic for a given set of inputs.
"""

from __future__ import annotations

import glob
import os
from collections import defaultdict
from pathlib import Path

from vtrack.errors import InputError

VIDEO_EXTENSIONS = frozenset({
    ".3gp", ".asf", ".avi", ".dv", ".flv", ".h264", ".264", ".h265", ".265", ".hevc",
    ".m2ts", ".m2v", ".m4v", ".mjpeg", ".mjpg", ".mkv", ".mov", ".mp4", ".mpeg", ".mpg",
    ".mts", ".mxf", ".ogv", ".ts", ".vob", ".webm", ".wmv", ".y4m",
})

RESERVED_NAMES = frozenset({"batch.csv"})


def is_video_name(path: str | os.PathLike) -> bool:
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


def _inside(path: str, folder: str | None) -> bool:
    if folder is None:
        return False
    real = os.path.realpath(path)
    return real == folder or real.startswith(folder + os.sep)


def scan_folder(folder: str | os.PathLike, exclude: str | None = None) -> list[Path]:
    """Video files under `folder` (recursive, sorted, hidden entries and `exclude` skipped)."""
    found: list[Path] = []
    for root, dirs, files in os.walk(folder, followlinks=False):
        dirs[:] = sorted(d for d in dirs
                         if not d.startswith(".") and not _inside(os.path.join(root, d), exclude))
        for name in sorted(files):
            if not name.startswith(".") and is_video_name(name):
                found.append(Path(root) / name)
    return found


def _has_magic(text: str) -> bool:
    return any(c in text for c in "*?[")


def discover(inputs: list[str], exclude: str | os.PathLike | None = None) -> list[Path]:
    """The videos named by `inputs`, in input order (each folder/pattern sorted), deduplicated.

    Raises InputError for an input that yields no video. `exclude` (the output folder) is
    never scanned.
    """
    excl = os.path.realpath(exclude) if exclude is not None else None
    videos: list[Path] = []
    seen: set[str] = set()
    for text in inputs:
        path = Path(text)
        if path.is_file():
            matches = [path]
        elif path.is_dir():
            matches = scan_folder(path, excl)
            if not matches:
                raise InputError(f"{text}: folder holds no video files "
                                 f"(looked for {', '.join(sorted(VIDEO_EXTENSIONS))})")
        elif _has_magic(text):
            matches = []
            for hit in sorted(glob.glob(text, recursive=True)):
                if _inside(hit, excl):
                    continue
                if os.path.isdir(hit):
                    matches.extend(scan_folder(hit, excl))
                elif os.path.isfile(hit) and is_video_name(hit):
                    matches.append(Path(hit))
            if not matches:
                raise InputError(f"{text}: pattern matches no video files")
        elif path.exists():
            raise InputError(f"{text}: not a regular file or folder")
        else:
            raise InputError(f"{text}: no such file or folder")
        for m in matches:
            key = os.path.realpath(m)
            if key not in seen:
                seen.add(key)
                videos.append(m)
    return videos


def _candidates(video: Path) -> list[str]:
    """Ever longer names for a video whose stem collides (nearest parent folder first)."""
    parents = [p for p in Path(os.path.abspath(video)).parent.parts
               if p not in ("", os.sep, "/") and not p.endswith((":\\", ":/"))]
    stem = video.stem
    names = ["_".join(parents[len(parents) - k:] + [stem]) for k in range(1, len(parents) + 1)]
    names.append("_".join(parents + [stem, video.suffix.lstrip(".") or "video"]))
    return names


def output_names(videos: list[Path]) -> list[str]:
    """One distinct folder name per video (see the module doc)."""
    groups: dict[str, list[int]] = defaultdict(list)
    for i, v in enumerate(videos):
        groups[v.stem].append(i)
    names: list[str] = [""] * len(videos)
    for stem, members in groups.items():
        if len(members) == 1 and stem not in RESERVED_NAMES:
            names[members[0]] = stem
            continue
        cands = {i: _candidates(videos[i]) for i in members}
        depth = max(len(c) for c in cands.values())
        for k in range(depth):
            picked = {i: c[min(k, len(c) - 1)] for i, c in cands.items()}
            if len(set(picked.values())) == len(members):
                break
        for i in members:
            names[i] = picked[i]
    # A prefixed name may still meet another video's plain stem (or itself repeat when two
    # paths differ only by a separator): number the later ones.
    taken: set[str] = set(RESERVED_NAMES)
    for i, name in enumerate(names):
        final, n = name, 1
        while final in taken:
            n += 1
            final = f"{name}-{n}"
        taken.add(final)
        names[i] = final
    return names
