"""Benchmark pose graphs by name: from a local mirror or downloaded once, always checksummed.

Two kinds of data are reachable from here.

*Public benchmarks* (INTEL, M3500, CSAIL, FR079, MIT, city10000, ring, …) are not shipped with
lagolib.  :func:`path` finds one of them

1. in the folder named by the environment variable ``LAGOLIB_DATA`` (a mirror laid out as the
   ``relpath`` column of :func:`info`), if that variable is set — and then *only* there: a missing
   file is an error, never a silent download; or
2. in lagolib's download cache (``LAGOLIB_CACHE``, default the user cache folder), fetched with
   `pooch <https://www.fatiando.org/pooch/>`_ from the public repository it comes from, pinned to
   a commit (never when ``LAGOLIB_OFFLINE=1``; a download waits at most ``LAGOLIB_TIMEOUT``
   seconds, default 20, for the network).

Either way the file's SHA-256 must equal the registry's, or :class:`~lagolib.errors.DatasetError`
is raised.

*Shipped examples* (``square_loop``, ``manhattan200``, ``grid100``) are small simulated graphs in
the repository's ``data/`` folder, made by ``data/make_data.py``; :func:`example` loads one with
its ground truth, offline.

Examples
--------
>>> from lagolib import datasets
>>> ex = datasets.example("square_loop")
>>> ex.graph.n, ex.truth.shape
(160, (160, 3))
>>> datasets.info("intel").vertices, datasets.info("intel").edges
(1228, 1483)
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import DatasetError
from .graph import PoseGraph
from .io import read, read_poses

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
        ``"graph"`` (g2o/TORO, read with :func:`lagolib.io.read`) or ``"poses"`` (ground truth,
        read with :func:`lagolib.io.read_poses`).
    vertices, edges : int
        Counts of vertices and edges in the file (``vertices`` is 0 for edge-only files).
    description : str
    """

    name: str
    relpath: str
    sha256: str
    url: str
    kind: str
    vertices: int
    edges: int
    description: str


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
    ]
}


def names():
    """Names of the registered benchmark files, sorted."""
    return sorted(_REGISTRY)


def info(name):
    """The :class:`Dataset` record of ``name``.

    Raises
    ------
    DatasetError
        If ``name`` is not registered (the message lists the names that are).
    """
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


def _check(d, p):
    st = p.stat()
    key = (str(p), st.st_size, st.st_mtime_ns)
    if _verified.get(key) != d.sha256:
        digest = _sha256(p)
        if digest != d.sha256:
            raise DatasetError(
                f"{p}: SHA-256 {digest} does not match the registry's {d.sha256} for dataset "
                f"{d.name!r}; the file is corrupt or a different version — replace it with the "
                f"file from {d.url}"
            )
        _verified[key] = d.sha256
    return p


def mirror():
    """The folder named by ``LAGOLIB_DATA`` as a Path, or None when the variable is unset or empty."""
    value = os.environ.get("LAGOLIB_DATA", "")
    return Path(value).expanduser() if value else None


def cache_dir():
    """Where downloads are kept: ``LAGOLIB_CACHE`` if set, else the user cache folder of lagolib."""
    value = os.environ.get("LAGOLIB_CACHE", "")
    if value:
        return Path(value).expanduser()
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
        with ``False``, raise instead.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    DatasetError
        Unknown name; ``LAGOLIB_DATA`` is set but lacks the file; the file's checksum differs
        from the registry's; or the file is not cached and ``download`` is False.
    """
    d = info(name)
    root = mirror()
    if root is not None:
        p = root / d.relpath
        if not p.is_file():
            raise DatasetError(
                f"LAGOLIB_DATA={root} has no file {d.relpath} (dataset {name!r}); put the file "
                f"from {d.url} there, or unset LAGOLIB_DATA to download it into the cache"
            )
        return _check(d, p)
    p = cache_dir() / _cached_name(d)
    if p.is_file():
        return _check(d, p)
    if not download or _offline():
        raise DatasetError(
            f"dataset {name!r} is not in the cache {cache_dir()} and download=False; call "
            f"lagolib.datasets.path({name!r}) once with network access, or set LAGOLIB_DATA to a mirror"
        )
    import pooch

    try:
        fetched = pooch.retrieve(
            d.url,
            known_hash=f"sha256:{d.sha256}",
            fname=_cached_name(d),
            path=cache_dir(),
            progressbar=False,
            downloader=pooch.HTTPDownloader(timeout=_download_timeout(), progressbar=False),
        )
    except ValueError as exc:  # pooch's checksum mismatch
        raise DatasetError(
            f"download of dataset {name!r} from {d.url} failed its checksum: {exc}"
        ) from exc
    except Exception as exc:
        raise DatasetError(
            f"could not download dataset {name!r} from {d.url}: {exc}; check the network, or set "
            "LAGOLIB_DATA to a folder that mirrors the files"
        ) from exc
    return Path(fetched)


def available(name):
    """True when :func:`path` would return without touching the network."""
    d = info(name)
    root = mirror()
    p = (root / d.relpath) if root is not None else cache_dir() / _cached_name(d)
    return p.is_file()


def _offline():
    """True when ``LAGOLIB_OFFLINE`` is set to a non-empty value other than ``0``: never download."""
    return os.environ.get("LAGOLIB_OFFLINE", "") not in ("", "0")


def _download_timeout():
    """Seconds a download may wait for the network (``LAGOLIB_TIMEOUT``, default 20)."""
    try:
        return max(1.0, float(os.environ.get("LAGOLIB_TIMEOUT", "20")))
    except ValueError:
        return 20.0


def load(name, *, download=True):
    """Read a registered benchmark file.

    Returns
    -------
    PoseGraph
        For ``kind == "graph"``.
    (ids, poses)
        For ``kind == "poses"`` (see :func:`lagolib.io.read_poses`).
    """
    d = info(name)
    p = path(name, download=download)
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
    simulated graph ``fallback`` is used instead and the printed line says how to get the real
    file.  A mirror that is set but broken is still an error (:func:`path`).

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
    d = info(name)
    if fallback not in _EXAMPLES:
        raise DatasetError(f"unknown example {fallback!r}; shipped: {', '.join(_EXAMPLES)}")
    if d.kind != "graph":
        raise DatasetError(f"dataset {name!r} holds {d.kind}, not a graph; use load({name!r})")
    try:
        graph = load(name, download=download)
    except DatasetError as exc:
        if mirror() is not None:  # a mirror that lacks or corrupts a file is the user's to fix
            raise
        ex = example(fallback)
        reason = "no network" if download and not _offline() else "downloads are off"
        note = (
            f"Using the shipped simulated graph {fallback!r} ({ex.graph.n} poses, {ex.graph.m} "
            f"edges) instead of {name!r} ({reason}). For the real file, run "
            f"lagolib.datasets.path({name!r}) once online, or set LAGOLIB_DATA to a mirror."
        )
        del exc
        if not quiet:
            print(note)
        return Loaded(ex.graph, fallback, False, ex.truth, note)
    note = f"Using the public benchmark {name!r} ({graph.n} poses, {graph.m} edges)."
    if not quiet:
        print(note)
    return Loaded(graph, name, True, None, note)


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
    if name not in _EXAMPLES:
        raise DatasetError(f"unknown example {name!r}; shipped: {', '.join(_EXAMPLES)}")
    folder = data_dir()
    graph = read(folder / f"{name}.g2o")
    ids, truth = read_poses(folder / f"{name}_truth.txt")
    if not np.array_equal(ids, graph.ids):
        raise DatasetError(f"{folder / (name + '_truth.txt')}: ids do not match {name}.g2o")
    return Example(name, graph, truth)
