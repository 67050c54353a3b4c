"""Benchmark pose graphs and laser logs by name: from a mirror or downloaded once, checksummed.

Two kinds of data are reachable from here.

*Public benchmarks* are not shipped with lagolib: the pose graphs (INTEL, M3500, CSAIL, FR079,
MIT, city10000, ring, …; kinds ``"graph"`` and ``"poses"``) and four Radish laser logs in Carmen
format (``intel_laser``, ``fr079_laser``, ``csail_laser``, ``aces_laser``; kind ``"laser"``, read
into a :class:`~lagolib.scans.LaserLog`).  :func:`path` finds one of them

1. in the folders named by the environment variable ``LAGOLIB_DATA`` (mirrors laid out as the
   ``relpath`` column of :func:`info`; several folders are separated by ``os.pathsep``, ``:`` on
   POSIX, as in ``PATH`` — e.g. ``posegraphs:laser`` — and the first that holds the file wins),
   if that variable is set — and then *only* there: a file none of them holds is an error,
   never a silent download; or
2. in lagolib's download cache (``LAGOLIB_CACHE``, default the user cache folder; created on the
   first download), fetched with `pooch <https://www.fatiando.org/pooch/>`_'s HTTP downloader
   from the public repository it comes from, pinned to a commit (never when ``LAGOLIB_OFFLINE``
   is ``1``; a download waits at most ``LAGOLIB_TIMEOUT`` seconds, default 20, for the network).
   A download goes to a temporary file in the cache folder — on Linux an anonymous one, which a
   process killed half-way leaves no trace of — and is moved into place only after its checksum
   matched; it prints nothing (no progress or log lines).

Either way the file's SHA-256 must equal the registry's, or :class:`~lagolib.errors.DatasetError`
is raised (for a cached file: "the cached file ... is corrupt").  A misconfiguration is named
as such: ``LAGOLIB_DATA`` (or one of its folders) naming a file, a missing folder or ``~user``
of an unknown user, ``LAGOLIB_CACHE`` naming a file, and ``LAGOLIB_OFFLINE``/``LAGOLIB_TIMEOUT``
values that mean nothing (an :class:`~lagolib.errors.OptionError`).

*Shipped examples* (``square_loop``, ``manhattan200``, ``grid100``) are small simulated graphs in
the repository's ``data/`` folder, made by ``data/make_data.py``; :func:`example` loads one with
its ground truth, offline.  A laser log's offline stand-in is a simulated log
(:func:`lagolib.laser_world.simulate_log`): :func:`load_laser_or_simulated` returns the real log
when it can be had, else the simulated one, and says which.

Examples
--------
>>> from lagolib import datasets
>>> ex = datasets.example("square_loop")
>>> ex.graph.n, ex.truth.shape
(160, (160, 3))
>>> datasets.info("intel").vertices, datasets.info("intel").edges
(1228, 1483)
>>> datasets.info("intel_laser").scans, datasets.info("intel_laser").beams
(910, 180)
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import math
import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from .checks import check_bool
from .errors import DatasetError, OptionError, OptionTypeError
from .graph import PoseGraph
from .io import read, read_poses
from .scans import LaserLog, read_carmen

__all__ = [
    "Dataset",
    "Example",
    "names",
    "info",
    "path",
    "available",
    "load",
    "Loaded",
    "load_or_example",
    "LoadedLog",
    "load_laser_or_simulated",
    "mirror",
    "mirrors",
    "example",
    "examples",
]


@dataclass(frozen=True)
class Dataset:
    """One registered benchmark file.

    Attributes
    ----------
    name : str
        Registry key.
    relpath : str
        Path inside a ``LAGOLIB_DATA`` mirror.
    sha256 : str
        Checksum of the file's bytes.
    url : str
        Where it is downloaded from (a public repository, pinned to a commit).
    kind : str
        ``"graph"`` (g2o/TORO, read with :func:`lagolib.io.read`), ``"poses"`` (ground truth,
        read with :func:`lagolib.io.read_poses`) or ``"laser"`` (a Carmen log, read with
        :func:`lagolib.scans.read_carmen`).
    vertices, edges : int
        Counts of vertices and edges in the file (``vertices`` is 0 for edge-only files; both
        are 0 for a laser log).
    description : str
    scans, beams : int
        A laser log's number of scans (``FLASER`` lines) and beams per scan; 0 for the other
        kinds.
    """

    name: str
    relpath: str
    sha256: str
    url: str
    kind: str
    vertices: int
    edges: int
    description: str
    scans: int = 0
    beams: int = 0


_NANO = "https://raw.githubusercontent.com/gisbi-kim/nano-pgo/b85562f0acda4d3e556f5b2d27c14156336df75b/data/"
_SESYNC = "https://raw.githubusercontent.com/david-m-rosen/SE-Sync/9b631b6b82d8aa7d32ab846412ae1c070412b7b6/data/"
_VERTIGO = (
    "https://raw.githubusercontent.com/OpenSLAM-org/openslam_vertigo/"
    "e57e88cbc1756070f37c6c32f87be947e7a72bb8/datasets/"
)
_SPARSIFY = (
    "https://raw.githubusercontent.com/Lecanyu/SparsifyPoseGraph/"
    "8a456d0164e92c34817a10aa456d8af12c2ddaf6/datasets/"
)
# the Radish logs as republished by acschaefer/ple (its readme credits Radish)
_CARMEN = (
    "https://raw.githubusercontent.com/acschaefer/ple/"
    "8af88b28759f8a48b1bf33083a85f2013907c41d/data/carmen/"
)


def _laser(name, file, sha256, scans, beams, description):
    """A Radish laser log: ``carmen/<file>`` in a mirror, its reference poses GMapping's."""
    return Dataset(
        name, f"carmen/{file}", sha256, _CARMEN + file, "laser", 0, 0, description, scans, beams
    )


_REGISTRY = {
    d.name: d
    for d in [
        Dataset(
            "intel",
            "carlone-nano-pgo/input_INTEL_g2o.g2o",
            "e648e42b1f24ab01cce76f56c8d8dad0b606f712afe2b92356bf26f195c602be",
            _NANO + "input_INTEL_g2o.g2o",
            "graph",
            1228,
            1483,
            "Intel Research Lab, Carlone's version (the INTEL of Carlone et al. 2011)",
        ),
        Dataset(
            "m3500",
            "carlone-nano-pgo/input_M3500_g2o.g2o",
            "1883593980e602b11bd0ba95799c969e59ee8a6892bdb2a3a48f495459efe9d8",
            _NANO + "input_M3500_g2o.g2o",
            "graph",
            3500,
            5453,
            "Olson's Manhattan world M3500, Carlone's version (duplicate edges merged)",
        ),
        Dataset(
            "csail_toro",
            "carlone-nano-pgo/CSAIL_P_toro.graph",
            "fcf4de76b262e7f58ea64b8c5db806fec926a519d2f5d85fcc9c553f8f82fa98",
            _NANO + "CSAIL_P_toro.graph",
            "graph",
            1045,
            1172,
            "MIT CSAIL building, TORO format (frame-i information)",
        ),
        Dataset(
            "fr079",
            "carlone-nano-pgo/FR079_P_toro.graph",
            "ba53624ae4ed843258359c8e5713e7456943b6daf2e4a17b800a90e170d7e659",
            _NANO + "FR079_P_toro.graph",
            "graph",
            989,
            1217,
            "Freiburg building 079, TORO format",
        ),
        Dataset(
            "csail",
            "se-sync/CSAIL.g2o",
            "66d99ac857a9849d814d214a9ebd0d4876d5d40f0a37be9330c1ff6e6e9daaa6",
            _SESYNC + "CSAIL.g2o",
            "graph",
            0,
            1172,
            "MIT CSAIL building, SE-Sync's g2o version (edges only)",
        ),
        Dataset(
            "mit",
            "se-sync/MIT.g2o",
            "e5922be0d0689c7a5bc04c58adf3a8e697e240bdd7691cc4218470eaf92956eb",
            _SESYNC + "MIT.g2o",
            "graph",
            808,
            827,
            "MIT Killian Court (Carlone's MITb)",
        ),
        Dataset(
            "city10000",
            "se-sync/city10000.g2o",
            "df5988994339e990be198a36e7f640e31a5a1b26df3ed400363fafc49d5ca630",
            _SESYNC + "city10000.g2o",
            "graph",
            10000,
            20687,
            "Kaess's simulated city10000 (iSAM)",
        ),
        Dataset(
            "intel_sesync",
            "se-sync/intel.g2o",
            "3e0724c048e0ba524be9dd268a8b78e19a2497043143584cbb61310638b15c4b",
            _SESYNC + "intel.g2o",
            "graph",
            1728,
            2512,
            "SE-Sync's intel (a different graph from Carlone's INTEL)",
        ),
        Dataset(
            "manhattan",
            "se-sync/manhattan.g2o",
            "6ae8d30971720c1af24a00c4b2dd5c5ddafbbbe488bfc771145c47decbffb248",
            _SESYNC + "manhattan.g2o",
            "graph",
            0,
            5453,
            "SE-Sync's M3500 (edges only, anisotropic information)",
        ),
        Dataset(
            "intel_g2o",
            "vertigo/intel/intel.g2o",
            "4d87aaf96e1e04e47c723c371386b15358c71e98c05dad16b786d585f9fd70ff",
            _VERTIGO + "intel/originalDataset/intel.g2o",
            "graph",
            943,
            1837,
            "intel as distributed with g2o (vertigo's copy)",
        ),
        Dataset(
            "intel_sparsify",
            "sparsify-posegraph/intel.g2o",
            "09b99e9c7e12343a6ee69eaff57e450f055a44bcca0ba44a10b0bd2fd34ed08c",
            _SPARSIFY + "intel.g2o",
            "graph",
            943,
            1833,
            "intel as distributed with g2o (SparsifyPoseGraph's copy)",
        ),
        Dataset(
            "m3500_olson",
            "vertigo/manhattan/Olson/manhattanOlson3500.g2o",
            "87a3ea13dbde2c4b164ddbefc74948a4b14b5b1b93c0829378c9696925fa7329",
            _VERTIGO + "manhattan/originalDataset/Olson/manhattanOlson3500.g2o",
            "graph",
            3500,
            5598,
            "Olson's original M3500 (duplicates kept, unwrapped angles)",
        ),
        Dataset(
            "m3500_olson_g2o",
            "vertigo/manhattan/g2o/manhattanOlson3500.g2o",
            "84d6ac6faffe2f120bd8df6f80185db0fafacdd9c0eedfa118ae475e035f9f40",
            _VERTIGO + "manhattan/originalDataset/g2o/manhattanOlson3500.g2o",
            "graph",
            3500,
            5598,
            "M3500 as distributed with g2o (non-odometric initial guess)",
        ),
        Dataset(
            "m3500_olson_truth",
            "vertigo/manhattan/groundTruth/manhattanOlson3500_nodes_groundTruth.dat",
            "8512b270849f2571ace2f5fac486d3ee9b686e8334c7c55a6f96c2025a413181",
            _VERTIGO + "manhattan/groundTruth/manhattanOlson3500_nodes_groundTruth.dat",
            "poses",
            3500,
            0,
            "ground-truth poses of Olson's M3500",
        ),
        Dataset(
            "ring",
            "vertigo/ring/ring.g2o",
            "786a004adc98e7a530d3ba3c11200f7d8ba6cad6ca59929d64e1cbbf164d49aa",
            _VERTIGO + "ring/originalDataset/ring.g2o",
            "graph",
            434,
            459,
            "Sünderhauf's ring (loop closures stored j < i)",
        ),
        Dataset(
            "ring_truth_graph",
            "vertigo/ring/groundTruth/ring.g2o",
            "7201bbf248670d71bd919062a806efa95589d01c26d1d1a12cee83f16f130a05",
            _VERTIGO + "ring/groundTruth/ring.g2o",
            "graph",
            434,
            459,
            "ring, noise-free measurements at the true poses",
        ),
        Dataset(
            "ring_truth",
            "vertigo/ring/groundTruth/poses.txt",
            "89294c68515cf833362d5f94f35a38879745f7d0a9fd22c86ce880b864fa3fe0",
            _VERTIGO + "ring/groundTruth/poses.txt",
            "poses",
            434,
            0,
            "ground-truth poses of ring",
        ),
        _laser(
            "intel_laser",
            "intel-corrected.log.gz",
            "71bef16e9926506cf7417995ef35ace09dbd5de067fd042a3aab85188b5480dc",
            910,
            180,
            "Intel Research Lab Seattle (Dirk Hähnel), Radish; poses GMapping's",
        ),
        _laser(
            "fr079_laser",
            "freiburg-079-corrected.log.gz",
            "0631d30baf4b9d1d209af47da9096e876e1b4cb3d5a2d68ef9c39c5a2360a466",
            4791,
            360,
            "Freiburg building 079 (Cyrill Stachniss), Radish; poses GMapping's",
        ),
        _laser(
            "csail_laser",
            "csail-corrected.log.gz",
            "a98de24fc319651f231f9a8625b78bf1972312b86f7b00d2ddc979c4ac92ae2d",
            406,
            361,
            "MIT CSAIL building, Radish; poses GMapping's",
        ),
        _laser(
            "aces_laser",
            "aces-corrected.log.gz",
            "5434d44384166250608a64d3a8c32de84512f82c46cb60a2657f138592024569",
            440,
            180,
            "UT Austin ACES building (Patrick Beeson), Radish; poses GMapping's",
        ),
    ]
}


def names():
    """Names of the registered benchmark files, sorted."""
    return sorted(_REGISTRY)


def _name(name, where, what="name"):
    """``name`` if it is a str; else an :class:`~lagolib.errors.OptionTypeError` naming ``where``."""
    if not isinstance(name, str):
        example = "'square_loop'" if what == "fallback" or where == "example" else "'intel'"
        if where == "load_laser_or_simulated":
            example = "'intel_laser'"
        raise OptionTypeError(
            f"{where}: {what} must be a str, one name such as {example}; got {name!r} "
            f"({type(name).__name__})"
        )
    return name


def info(name):
    """The :class:`Dataset` record of ``name``.

    Raises
    ------
    DatasetError
        If ``name`` is not registered (the message lists the names that are).
    OptionTypeError
        If ``name`` is not a str.
    """
    _name(name, "info")
    try:
        return _REGISTRY[name]
    except KeyError:
        raise DatasetError(f"unknown dataset {name!r}; known: {', '.join(names())}") from None


_verified = {}


def _sha256(p):
    h = hashlib.sha256()
    with open(p, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _unavailable(message, reason, advice=None):
    """A DatasetError for a file that cannot be had now, with attributes ``reason`` (why, in a
    few words) and ``advice`` (how to get it), for :func:`load_or_example`'s note and the CLI."""
    exc = DatasetError(message)
    exc.reason = reason
    exc.advice = advice or "run lagolib.datasets.path({name!r}) once online"
    return exc


def _check(d, p, cached=False):
    st = p.stat()
    key = (str(p), st.st_size, st.st_mtime_ns)
    if _verified.get(key) != d.sha256:
        digest = _sha256(p)
        if digest != d.sha256:
            if cached:
                raise _unavailable(
                    f"the cached file {p} of dataset {d.name!r} is corrupt: its SHA-256 {digest} "
                    f"does not match the registry's {d.sha256}; delete it, and "
                    f"lagolib.datasets.path({d.name!r}) downloads it again",
                    f"the cached file {p} is corrupt (its SHA-256 differs from the registry's)",
                    "delete it and run lagolib.datasets.path({name!r}) once online",
                )
            raise DatasetError(
                f"{p}: SHA-256 {digest} does not match the registry's {d.sha256} for dataset "
                f"{d.name!r}; the file is corrupt or a different version — replace it with the "
                f"file from {d.url}"
            )
        _verified[key] = d.sha256
    return p


def _folder(variable, value, whole=None):
    """The folder ``value`` of the environment variable ``variable`` (``~`` expanded); a
    DatasetError when it names a file or a user that does not exist.  ``whole`` is the
    variable's whole value when ``value`` is one of its several folders (``LAGOLIB_DATA``)."""
    said = f"{variable}={value}" if whole is None else f"{variable}={whole}: its folder {value}"
    try:
        folder = Path(value).expanduser()
    except RuntimeError:  # '~someone' of a user that does not exist, or no home folder
        user = value.split("/", 1)[0].split(os.sep, 1)[0]
        raise DatasetError(
            f"{said}: cannot expand {user!r} (no such user, or no home folder); "
            "give the folder's full path"
        ) from None
    if folder.exists() and not folder.is_dir():
        fix = f"set {variable} to a folder" if whole is None else "name folders only"
        raise DatasetError(f"{said} is a file, not a folder; {fix}, or unset {variable}")
    return folder


def _folder_variable(variable):
    """The folder named by the environment variable ``variable`` (``~`` expanded), or None when
    it is unset or empty; a DatasetError when it names a file or a user that does not exist."""
    value = os.environ.get(variable, "")
    return _folder(variable, value) if value else None


def mirrors():
    """The folders named by ``LAGOLIB_DATA``, in lookup order; ``[]`` when it is unset or empty.

    ``LAGOLIB_DATA`` holds one folder, or several separated by ``os.pathsep`` (``:`` on POSIX,
    ``;`` on Windows), as ``PATH`` does: e.g. the pose-graph mirror and the laser-log mirror,
    ``/data/posegraphs:/data/laser``.  Empty entries (a trailing ``:``) are ignored.  A file is
    taken from the first folder that has it (and must pass its checksum there).

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    DatasetError
        ``LAGOLIB_DATA`` or one of its folders names a file, a folder that does not exist, or
        ``~user`` of an unknown user (the message names which).

    Examples
    --------
    >>> import os
    >>> from unittest import mock
    >>> from lagolib import datasets
    >>> a, b = os.path.dirname(datasets.__file__), os.path.dirname(os.__file__)
    >>> with mock.patch.dict(os.environ, LAGOLIB_DATA=a + os.pathsep + b + os.pathsep):
    ...     print([str(f) for f in datasets.mirrors()] == [a, b], datasets.mirror() == Path(a))
    True True
    >>> with mock.patch.dict(os.environ, LAGOLIB_DATA=""):
    ...     print(datasets.mirrors(), datasets.mirror())
    [] None
    """
    value = os.environ.get("LAGOLIB_DATA", "")
    entries = [e for e in value.split(os.pathsep) if e]
    whole = value if len(entries) > 1 else None
    folders = []
    for entry in entries:
        folder = _folder("LAGOLIB_DATA", entry, whole)
        if not folder.is_dir():
            if whole is None:
                raise DatasetError(
                    f"LAGOLIB_DATA={value}: no such folder; set LAGOLIB_DATA to the folder that "
                    "mirrors the benchmarks, or unset it to use the download cache"
                )
            raise DatasetError(
                f"LAGOLIB_DATA={value}: its folder {entry} does not exist; list only existing "
                f"folders (separated by {os.pathsep!r}), or unset LAGOLIB_DATA to use the "
                "download cache"
            )
        folders.append(folder)
    return folders


def mirror():
    """The first folder named by ``LAGOLIB_DATA`` as a Path, or None when it is unset or empty.

    With one folder in ``LAGOLIB_DATA``, that folder; with several, the first (all of them are
    checked, and :func:`mirrors` lists them).

    Raises
    ------
    DatasetError
        As :func:`mirrors`: ``LAGOLIB_DATA`` names a file, a folder that does not exist, or
        ``~user`` of an unknown user.
    """
    folders = mirrors()
    return folders[0] if folders else None


def _in_mirrors(d, roots):
    """The first ``root / d.relpath`` that is a file, or None."""
    for root in roots:
        if (root / d.relpath).is_file():
            return root / d.relpath
    return None


def cache_dir():
    """Where downloads are kept: ``LAGOLIB_CACHE`` if set, else the user cache folder of lagolib.

    The folder is created by the first download.

    Raises
    ------
    DatasetError
        ``LAGOLIB_CACHE`` names a file, or ``~user`` of an unknown user.
    """
    folder = _folder_variable("LAGOLIB_CACHE")
    if folder is not None:
        return folder
    import pooch

    return Path(pooch.os_cache("lagolib"))


def _cached_name(d):
    return d.relpath.replace("/", "__")


def path(name, *, download=True):
    """Local path of a registered benchmark file, checksum verified.

    Parameters
    ----------
    name : str
        A name from :func:`names`.
    download : bool
        When ``LAGOLIB_DATA`` is unset and the file is not cached yet, download it (default);
        with ``False``, raise instead.  ``LAGOLIB_OFFLINE=1`` forbids downloads whatever this
        says.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    DatasetError
        Unknown name; ``LAGOLIB_DATA`` is set but none of its folders has the file;
        ``LAGOLIB_DATA`` (one of its folders) or ``LAGOLIB_CACHE`` names a file or
        (``LAGOLIB_DATA``) a missing folder; the file's
        checksum differs from the registry's (a mirrored, cached or downloaded file); the file
        is not cached and downloads are off (``download=False`` or ``LAGOLIB_OFFLINE``); the
        download failed (the message says why in one sentence).
    OptionTypeError
        ``name`` is not a str or ``download`` is not a bool.
    OptionError
        ``LAGOLIB_OFFLINE`` or ``LAGOLIB_TIMEOUT`` holds a value that means nothing.
    """
    d = info(name)
    download = check_bool(download, "download", "path")
    roots = mirrors()
    if roots:
        p = _in_mirrors(d, roots)
        if p is None and len(roots) == 1:
            raise DatasetError(
                f"LAGOLIB_DATA={roots[0]} has no file {d.relpath} (dataset {name!r}); put the "
                f"file from {d.url} there, or add the folder that has it to LAGOLIB_DATA "
                f"(folders separated by {os.pathsep!r}), or unset LAGOLIB_DATA to download it "
                "into the cache"
            )
        if p is None:
            raise DatasetError(
                f"none of the LAGOLIB_DATA folders {', '.join(map(str, roots))} has the file "
                f"{d.relpath} (dataset {name!r}); put the file from {d.url} into one of them, or "
                "unset LAGOLIB_DATA to download it into the cache"
            )
        return _check(d, p)
    folder = cache_dir()
    p = folder / _cached_name(d)
    if p.is_file():
        return _check(d, p, cached=True)
    offline = _offline()
    if offline or not download:
        missing = "" if folder.is_dir() else f" (the folder {folder} does not exist yet)"
        why = f"LAGOLIB_OFFLINE={os.environ['LAGOLIB_OFFLINE']}" if offline else "download=False"
        unset = "unset LAGOLIB_OFFLINE and " if offline else ""
        raise _unavailable(
            f"dataset {name!r} is not in the cache {folder}{missing}, and downloads are off "
            f"({why}); {unset}call lagolib.datasets.path({name!r}) once with network access, or "
            "set LAGOLIB_DATA to a mirror",
            f"it is not in the cache, and downloads are off ({why})",
            unset + "run lagolib.datasets.path({name!r}) once online",
        )
    return _download(d, folder, p)


def available(name):
    """True when :func:`path` would return without touching the network.

    Raises
    ------
    DatasetError
        As :func:`path` does for an unknown name or an unusable ``LAGOLIB_DATA``/``LAGOLIB_CACHE``.
    """
    d = info(name)
    roots = mirrors()
    if roots:
        return _in_mirrors(d, roots) is not None
    return (cache_dir() / _cached_name(d)).is_file()


_OFF = ("", "0", "false", "no", "off")
_ON = ("1", "true", "yes", "on")


def _offline():
    """True when ``LAGOLIB_OFFLINE`` says never download (``1``, ``true``, ``yes``, ``on``).

    Unset, empty, ``0``, ``false``, ``no`` and ``off`` allow downloads; anything else is an
    :class:`~lagolib.errors.OptionError` (a typo must not silently allow or forbid downloads).
    """
    value = os.environ.get("LAGOLIB_OFFLINE", "").strip().lower()
    if value in _OFF:
        return False
    if value in _ON:
        return True
    raise OptionError(
        f"LAGOLIB_OFFLINE={os.environ['LAGOLIB_OFFLINE']!r} means neither on nor off; set it to 1 "
        "(never download) or 0 (download when needed), or unset it"
    )


def _download_timeout():
    """Seconds a download may wait for the network (``LAGOLIB_TIMEOUT``, default 20)."""
    value = os.environ.get("LAGOLIB_TIMEOUT", "").strip()
    if not value:
        return 20.0
    try:
        seconds = float(value)
    except ValueError:
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds > 0):
        raise OptionError(
            f"LAGOLIB_TIMEOUT={os.environ['LAGOLIB_TIMEOUT']!r} must be a positive number of "
            "seconds (default 20)"
        )
    return seconds


# ---------------------------------------------------------------------- downloads
class _Hashing:
    """The file object a downloader writes into: bytes go to ``fd`` and into a SHA-256."""

    def __init__(self, fd):
        self.fd, self.sha, self.size = fd, hashlib.sha256(), 0

    def write(self, data):
        view = memoryview(data)
        while view:
            view = view[os.write(self.fd, view) :]
        self.sha.update(data)
        self.size += len(data)
        return len(data)

    def flush(self):
        pass


def _stale_parts(folder, fname):
    """Remove ``.FNAME.PID.*.part`` files of processes that no longer run (killed downloads)."""
    if os.name != "posix":  # pragma: no cover (os.kill(pid, 0) would end the process there)
        return
    for part in folder.glob(f".{fname}.*.part"):
        fields = part.name[len(fname) + 2 :].split(".")
        with contextlib.suppress(ValueError, OSError):
            try:
                os.kill(int(fields[0]), 0)
            except ProcessLookupError:
                part.unlink()


def _part_name(folder, fname):
    return folder / f".{fname}.{os.getpid()}.{secrets.token_hex(4)}.part"


@contextlib.contextmanager
def _partial(folder, fname):
    """``(fd, name)`` of a fresh file in ``folder`` that a killed process leaves no trace of.

    On Linux the file is anonymous (``O_TMPFILE``): it has no name until :func:`_publish` links
    it into place, and the kernel frees it when the process dies, however it dies.  Elsewhere it
    is ``.FNAME.PID.XXXXXXXX.part``, removed on any exception, and by the next download after a
    process killed outright (:func:`_stale_parts`).  ``name`` is None for an anonymous file.
    """
    fd = name = None
    flag = getattr(os, "O_TMPFILE", 0)
    if flag and os.path.isdir("/proc/self/fd"):
        with contextlib.suppress(OSError):  # a file system without O_TMPFILE: the named file
            fd = os.open(folder, flag | os.O_RDWR, 0o644)
    if fd is None:
        name = _part_name(folder, fname)
        fd = os.open(name, os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o644)
    try:
        yield fd, name
    finally:
        os.close(fd)
        if name is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(name)


def _publish(fd, name, target):
    """Move the finished download into place: atomically, never a half-written ``target``."""
    os.fsync(fd)
    if name is None:
        # linkat(AT_SYMLINK_FOLLOW) of /proc/self/fd/N names the anonymous file; the dir fds make
        # Python call linkat rather than link, which would not follow the /proc link
        folder = os.open(target.parent, os.O_RDONLY)
        try:
            link = functools.partial(
                os.link, f"/proc/self/fd/{fd}", src_dir_fd=folder, dst_dir_fd=folder
            )
            try:
                link(target.name)  # atomic: the complete file appears under its name at once
                return
            except FileExistsError:  # another process finished first: replace its copy
                name = _part_name(target.parent, target.name)
                link(name.name)
            except OSError:  # linkat refused (a restricted /proc): copy into a named file
                name = _part_name(target.parent, target.name)
                try:
                    with open(name, "xb") as out:
                        os.lseek(fd, 0, os.SEEK_SET)
                        for block in iter(lambda: os.read(fd, 1 << 20), b""):
                            out.write(block)
                except BaseException:
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(name)
                    raise
        finally:
            os.close(folder)
    try:
        os.replace(name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(name)
        raise


def _why_failed(exc, url):
    """One short sentence for a failed download (not urllib3's retry report)."""
    import requests

    text, e = "", exc
    for _ in range(20):  # the whole chain: requests wraps urllib3, which wraps the socket error
        if e is None:
            break
        text += f" {type(e).__name__} {e}"
        e = e.__cause__ or e.__context__
    host = urlsplit(url).hostname or url
    seconds = f"{_download_timeout():g} s (LAGOLIB_TIMEOUT)"
    if isinstance(exc, requests.HTTPError) and exc.response is not None:
        r = exc.response
        return f"{host} answered HTTP {r.status_code} {r.reason or ''}".rstrip()
    if "NameResolutionError" in text or "Failed to resolve" in text or "gaierror" in text:
        return f"cannot look up the host {host} (no network, or no DNS)"
    if isinstance(exc, requests.ConnectTimeout):
        return f"{host} did not answer within {seconds}"
    if isinstance(exc, requests.Timeout):
        return f"{host} sent nothing for {seconds}"
    if "ConnectionRefused" in text or "Connection refused" in text:
        return f"{host} refused the connection"
    if isinstance(exc, requests.exceptions.SSLError):
        return f"the TLS connection to {host} failed (a proxy, or the system's certificates?)"
    if "IncompleteRead" in text or "Connection broken" in text:
        return f"the connection to {host} broke off before the whole file arrived"
    if isinstance(exc, requests.ConnectionError):
        return f"no connection to {host}"
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror + (f": {exc.filename}" if exc.filename else "")
    return f"{type(exc).__name__}: {' '.join(str(exc).split())[:120]}"


def _download(d, folder, target):
    """Download ``d`` into ``target`` (in ``folder``, created if needed), checksum verified."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        why = exc.strerror or str(exc)
        if os.environ.get("LAGOLIB_CACHE"):  # the user's setting: theirs to fix, never a fallback
            raise DatasetError(
                f"LAGOLIB_CACHE={folder}: cannot create the folder ({why}); set LAGOLIB_CACHE to "
                "a folder you can write, or unset it"
            ) from None
        raise _unavailable(
            f"the cache folder {folder} cannot be created ({why}); set LAGOLIB_CACHE to a "
            "folder you can write, or LAGOLIB_DATA to a mirror",
            f"the cache folder {folder} cannot be created ({why})",
        ) from None
    import pooch

    downloader = pooch.HTTPDownloader(timeout=_download_timeout(), progressbar=False)
    _stale_parts(folder, target.name)
    try:
        with _partial(folder, target.name) as (fd, name):
            out = _Hashing(fd)
            downloader(d.url, out, None)
            digest = out.sha.hexdigest()
            if digest != d.sha256:
                raise _unavailable(
                    f"download of dataset {d.name!r} from {d.url} failed its checksum: SHA-256 "
                    f"{digest} of {out.size} bytes, the registry's {d.sha256}; nothing was "
                    "kept in the cache (the server may hold a different version)",
                    "the downloaded file failed its checksum",
                )
            _publish(fd, name, target)
    except DatasetError:
        raise
    except Exception as exc:
        why = _why_failed(exc, d.url)
        raise _unavailable(
            f"could not download dataset {d.name!r} from {d.url}: {why}; check the network, or "
            "set LAGOLIB_DATA to a folder that mirrors the files",
            f"the download failed: {why}",
        ) from exc
    _verified[(str(target), *_stat_key(target))] = d.sha256
    return target


def _stat_key(p):
    st = p.stat()
    return st.st_size, st.st_mtime_ns


def load(name, *, download=True):
    """Read a registered benchmark file.

    Returns
    -------
    PoseGraph
        For ``kind == "graph"``.
    (ids, poses)
        For ``kind == "poses"`` (see :func:`lagolib.io.read_poses`).
    LaserLog
        For ``kind == "laser"`` (:func:`lagolib.scans.read_carmen`), named ``name``: ``reference``
        holds the log's corrected poses — GMapping's estimate, not ground truth.
    """
    d = info(name)
    p = path(name, download=download)
    if d.kind == "laser":
        return read_carmen(p, name=name)
    return read(p) if d.kind == "graph" else read_poses(p)


@dataclass(frozen=True)
class Loaded:
    """What :func:`load_or_example` found.

    Attributes
    ----------
    graph : PoseGraph
    name : str
        The benchmark's name when ``real``, else the shipped example's.
    real : bool
        True for the public benchmark, False for the shipped stand-in.
    truth : ndarray or None
        Ground truth of the stand-in (shipped examples have it), else None.
    note : str
        The one line printed: what is used and, for the stand-in, how to get the real file.
    """

    graph: PoseGraph
    name: str
    real: bool
    truth: np.ndarray | None
    note: str


def load_or_example(name, fallback, *, download=True, quiet=False):
    """A public benchmark when it can be had, else a shipped example — and one line saying which.

    The chapters call this: the benchmark comes from ``LAGOLIB_DATA``, the cache, or (when
    ``download`` and the network is there) a checksummed download; when none works, the shipped
    simulated graph ``fallback`` is used instead and the printed line says why — downloads off
    (``LAGOLIB_OFFLINE`` or ``download=False``), the download's failure in one sentence, or a
    corrupt cached file — and how to get the real file.  A mirror that is set but broken, and an
    unusable ``LAGOLIB_DATA``/``LAGOLIB_CACHE``/``LAGOLIB_OFFLINE``, are still errors
    (:func:`path`).  A download prints nothing but this line (no progress or log lines).

    Parameters
    ----------
    name : str
        A registered benchmark (:func:`names`).
    fallback : str
        A shipped example (:func:`examples`).
    download : bool
        Try the network when the file is neither mirrored nor cached.
    quiet : bool
        Do not print the line (it is in :attr:`Loaded.note` either way).

    Returns
    -------
    Loaded
    """
    where = "load_or_example"
    d = info(_name(name, where))
    _name(fallback, where, "fallback")
    download = check_bool(download, "download", where)
    quiet = check_bool(quiet, "quiet", where)
    if fallback not in _EXAMPLES:
        raise DatasetError(f"unknown example {fallback!r}; shipped: {', '.join(_EXAMPLES)}")
    if d.kind == "laser":
        raise DatasetError(
            f"dataset {name!r} is a laser log, not a graph; use "
            f"load_laser_or_simulated({name!r}) or load({name!r})"
        )
    if d.kind != "graph":
        raise DatasetError(f"dataset {name!r} holds {d.kind}, not a graph; use load({name!r})")
    had = mirror() is not None or available(name)
    try:
        graph = load(name, download=download)
    except DatasetError as exc:
        reason = getattr(exc, "reason", None)
        if reason is None:  # a mirror that lacks or corrupts a file is the user's to fix
            raise
        ex = example(fallback)
        note = (
            f"Using the shipped simulated graph {fallback!r} ({ex.graph.n} poses, {ex.graph.m} "
            f"edges) instead of {name!r}: {reason}. For the real file, "
            f"{exc.advice.format(name=name)}, or set LAGOLIB_DATA to a mirror."
        )
        if not quiet:
            print(note)
        return Loaded(ex.graph, fallback, False, ex.truth, note)
    got = "" if had else f"; downloaded from {d.url} into {cache_dir()}"
    note = f"Using the public benchmark {name!r} ({graph.n} poses, {graph.m} edges{got})."
    if not quiet:
        print(note)
    return Loaded(graph, name, True, None, note)


@dataclass(frozen=True)
class LoadedLog:
    """What :func:`load_laser_or_simulated` found: a real laser log or the simulated stand-in.

    Attributes
    ----------
    log : LaserLog
        The scans.  A real log's ``reference`` is GMapping's estimate (``reference_kind
        "gmapping"``); the simulated log's is the ground truth (``"truth"``).
    source : str
        The registry name (e.g. ``"intel_laser"``) of the real log, or ``"simulated"``.
    offline : bool
        True when the simulated stand-in is used (the real log could not be had).
    note : str
        The one line printed: what is used and, for the stand-in, why and how to get the real log.
    """

    log: LaserLog
    source: str
    offline: bool
    note: str


def load_laser_or_simulated(name, *, download=True, quiet=False):
    """A Radish laser log when it can be had, else a simulated one — and one line saying which.

    The laser-log counterpart of :func:`load_or_example`, with the same rules: the log comes
    from ``LAGOLIB_DATA``, the cache, or (when ``download`` and the network is there) a
    checksummed download; when none works — downloads off (``LAGOLIB_OFFLINE`` or
    ``download=False``), a failed download, a corrupt cached file — the simulated laser world of
    :func:`lagolib.laser_world.simulate_log` (its defaults: seeded, so every run gives the same
    log) is used instead, and the printed line says why and how to get the real log.  A mirror
    that is set but lacks or corrupts the file, and an unusable ``LAGOLIB_DATA``/
    ``LAGOLIB_CACHE``/``LAGOLIB_OFFLINE``, are still errors (:func:`path`).

    Parameters
    ----------
    name : str
        A registered laser log: ``"intel_laser"``, ``"fr079_laser"``, ``"csail_laser"`` or
        ``"aces_laser"``.
    download : bool
        Try the network when the log is neither mirrored nor cached.
    quiet : bool
        Do not print the line (it is in :attr:`LoadedLog.note` either way).

    Returns
    -------
    LoadedLog
        ``source`` is ``name`` and ``offline`` False for the real log; ``"simulated"`` and True
        for the stand-in.

    Raises
    ------
    DatasetError
        ``name`` is not a laser log; or as :func:`path`, for a mirror without the file or with a
        corrupt copy.

    Examples
    --------
    Offline, with no mirror and an empty cache, the simulated office stands in:

    >>> import os, tempfile
    >>> from unittest import mock
    >>> with tempfile.TemporaryDirectory() as cache, mock.patch.dict(
    ...     os.environ, LAGOLIB_DATA="", LAGOLIB_OFFLINE="1", LAGOLIB_CACHE=cache
    ... ):
    ...     loaded = load_laser_or_simulated("intel_laser", quiet=True)
    >>> loaded.source, loaded.offline, loaded.log.reference_kind
    ('simulated', True, 'truth')
    >>> loaded.note.startswith("Using a simulated laser log (")
    True
    """
    where = "load_laser_or_simulated"
    d = info(_name(name, where))
    download = check_bool(download, "download", where)
    quiet = check_bool(quiet, "quiet", where)
    if d.kind != "laser":
        lasers = ", ".join(n for n in names() if _REGISTRY[n].kind == "laser")
        raise DatasetError(
            f"{where}: dataset {name!r} is a {d.kind} file, not a laser log; laser logs: {lasers}"
        )
    had = mirror() is not None or available(name)
    try:
        log = load(name, download=download)
    except DatasetError as exc:
        reason = getattr(exc, "reason", None)
        if reason is None:  # a mirror that lacks or corrupts a file is the user's to fix
            raise
        from .laser_world import simulate_log

        sim = simulate_log()
        k, n = sim.ranges.shape
        note = (
            f"Using a simulated laser log ({k} scans of {n} beams, its reference poses the ground "
            f"truth) instead of {name!r}: {reason}. For the real log, "
            f"{exc.advice.format(name=name)}, or set LAGOLIB_DATA to a mirror."
        )
        if not quiet:
            print(note)
        return LoadedLog(sim, "simulated", True, note)
    got = "" if had else f"; downloaded from {d.url} into {cache_dir()}"
    k, n = log.ranges.shape
    note = (
        f"Using the Radish laser log {name!r} ({k} scans of {n} beams; its reference poses are "
        f"GMapping's estimate, not ground truth{got})."
    )
    if not quiet:
        print(note)
    return LoadedLog(log, name, False, note)


# ---------------------------------------------------------------------- shipped examples


@dataclass(frozen=True)
class Example:
    """A shipped simulated graph and its ground truth.

    Attributes
    ----------
    name : str
    graph : PoseGraph
        Noisy measurements; poses = the odometry guess.
    truth : ndarray, shape (n, 3)
        Ground-truth poses, rows aligned with ``graph.poses``.
    """

    name: str
    graph: PoseGraph
    truth: np.ndarray


_EXAMPLES = ("square_loop", "manhattan200", "grid100")


def examples():
    """Names of the shipped examples."""
    return list(_EXAMPLES)


def data_dir():
    """The folder of the shipped examples (inside the installed package, or the repository's ``data/``)."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "_data", here.parent / "data"):
        if (candidate / "square_loop.g2o").is_file():
            return candidate
    raise DatasetError(
        f"lagolib's shipped data folder is missing (looked in {here / '_data'} and {here.parent / 'data'})"
    )


def example(name):
    """Load a shipped example graph with its ground truth (offline).

    Parameters
    ----------
    name : {"square_loop", "manhattan200", "grid100"}
        ``square_loop``: four laps of a square, loop closures between laps; ``manhattan200``: a
        200-pose random walk on a lattice with loop closures on revisits (after Olson's M3500);
        ``grid100``: 100 poses on a grid, after Lodi Rizzini §IV-B.  ``data/README.md`` says how
        each was made.

    Returns
    -------
    Example
    """
    if _name(name, "example") not in _EXAMPLES:
        raise DatasetError(f"unknown example {name!r}; shipped: {', '.join(_EXAMPLES)}")
    folder = data_dir()
    graph = read(folder / f"{name}.g2o")
    ids, truth = read_poses(folder / f"{name}_truth.txt")
    if not np.array_equal(ids, graph.ids):
        raise DatasetError(f"{folder / (name + '_truth.txt')}: ids do not match {name}.g2o")
    return Example(name, graph, truth)
