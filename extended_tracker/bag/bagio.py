"""
Bag input and output with rosbags (no ROS installation needed).

The custom message types of ``extended_tracker_msgs`` are registered in a rosbags
typestore from their ``.msg`` definitions, so bags written here carry the definition and
``ros2 bag play`` on a Jazzy install can replay them.
"""

from __future__ import annotations

from contextlib import contextmanager
from functools import lru_cache
import os
from pathlib import Path
import shutil
import sys
import tempfile

from .. import stopping
from ..errors import BagError

MSG_PACKAGE = 'extended_tracker_msgs'
MSG_NAMES = ('ExtendedObject', 'ExtendedObjectArray')


def message_dirs() -> list[Path]:
    """Candidate ``msg`` folders: ament prefixes, this interpreter's prefix, the source tree."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    dirs = [Path(p) / 'share' / MSG_PACKAGE / 'msg' for p in prefixes]
    dirs.append(Path(__file__).resolve().parents[2] / 'interfaces' / MSG_PACKAGE / 'msg')
    return dirs


def find_msg_definitions() -> dict[str, str]:
    """
    Return the ``.msg`` texts of extended_tracker_msgs keyed by full type name.

    Raises
    ------
    BagError
        When no installed or source copy of the definitions is found.

    """
    for folder in message_dirs():
        if all((folder / f'{n}.msg').is_file() for n in MSG_NAMES):
            return {
                f'{MSG_PACKAGE}/msg/{n}': (folder / f'{n}.msg').read_text() for n in MSG_NAMES
            }
    searched = ', '.join(str(d) for d in message_dirs())
    raise BagError(f'extended_tracker_msgs definitions not found (searched {searched})')


@lru_cache(maxsize=1)
def message_typestore():
    """Return a ROS 2 Jazzy rosbags typestore with extended_tracker_msgs registered."""
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, text in find_msg_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


SCAN_TYPE = 'sensor_msgs/msg/LaserScan'
TRACKS_TYPE = 'extended_tracker_msgs/msg/ExtendedObjectArray'
MARKERS_TYPE = 'visualization_msgs/msg/MarkerArray'

def scan_data(scan) -> dict:
    """
    Nested plain data of a LaserScan for :func:`build_message` (ROS 2 fields): a message
    read from a ROS 1 or ROS 2 bag (a ROS 1 header's ``seq`` is left out) or the
    simulator's scan (which has no time increment or intensities: 0 and none).
    """
    import numpy as np

    stamp = scan.header.stamp
    return {
        'header': {'stamp': {'sec': stamp.sec, 'nanosec': stamp.nanosec},
                   'frame_id': scan.header.frame_id},
        'angle_min': scan.angle_min, 'angle_max': scan.angle_max,
        'angle_increment': scan.angle_increment,
        'time_increment': getattr(scan, 'time_increment', 0.0),
        'scan_time': scan.scan_time, 'range_min': scan.range_min,
        'range_max': scan.range_max, 'ranges': np.asarray(scan.ranges, np.float32),
        'intensities': np.asarray(getattr(scan, 'intensities', ()), np.float32),
    }


_BASE_DEFAULT = {'bool': False, 'string': ''}
_NUMPY_OF = {'bool': 'bool', 'int8': 'int8', 'uint8': 'uint8', 'byte': 'uint8',
             'char': 'uint8', 'int16': 'int16', 'uint16': 'uint16', 'int32': 'int32',
             'uint32': 'uint32', 'int64': 'int64', 'uint64': 'uint64',
             'float32': 'float32', 'float64': 'float64'}


def build_message(store, typename: str, data: dict | None = None):
    """
    A rosbags message of ``typename`` from nested plain data; absent fields get defaults.

    Raises
    ------
    BagError
        On a field name the type does not have.

    """
    import numpy as np

    data = data or {}
    _, fields = store.fielddefs[typename]
    names = {name for name, _ in fields}
    unknown = set(data) - names
    if unknown:
        raise BagError(f'{typename} has no field(s) {sorted(unknown)}')
    kwargs = {}
    for name, (kind, detail) in fields:
        value = data.get(name)
        kwargs[name] = _build_field(store, kind, detail, value, np)
    return store.types[typename](**kwargs)


def _build_field(store, kind, detail, value, np):
    # rosbags Nodetype: 1 BASE, 2 NAME (nested message), 3 ARRAY, 4 SEQUENCE
    kind = int(kind)
    if kind == 1:                                   # BASE
        base = detail[0]
        if value is None:
            return _BASE_DEFAULT.get(base, 0.0 if base.startswith('float') else 0)
        if base == 'string':
            return str(value)
        if base == 'bool':
            return bool(value)
        return float(value) if base.startswith('float') else int(value)
    if kind == 2:                                   # NAME: nested message
        return build_message(store, detail, value)
    # ARRAY (3) or SEQUENCE (4): detail = ((subkind, subdetail), length)
    (subkind, subdetail), length = detail
    if int(subkind) == 1 and subdetail[0] != 'string':
        dtype = _NUMPY_OF[subdetail[0]]
        if value is None:
            return np.zeros(length if int(kind) == 3 else 0, dtype=dtype)
        return np.asarray(value, dtype=dtype)
    items = [] if value is None else list(value)
    if int(kind) == 3 and not items:
        items = [None] * length
    return [_build_field(store, subkind, subdetail, v, np) for v in items]


class _Rosbag2Folder(type(Path())):
    """
    A ROS 2 bag folder's path that never reads as a ROS 1 file: rosbags' AnyReader takes
    every path ending in ``.bag`` for a ROS 1 bag, and ``ros2 bag record -o run.bag`` (or
    ``extended-tracker simulate run.bag``) makes a folder of that name.
    """

    @property
    def suffix(self) -> str:
        return ''


def _open_reader(p: Path):
    """
    An open rosbags AnyReader on the bag at ``p``. A ROS 2 bag that stores no message
    definitions (sqlite3 bags recorded before Iron, e.g. on Humble) is read with the
    standard Jazzy types; LaserScan has not changed between the distributions.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    reader = AnyReader([_Rosbag2Folder(p) if p.is_dir() else p],
                       default_typestore=get_typestore(Stores.ROS2_JAZZY))
    reader.open()
    return reader


def open_scans(path, scan_topic=None):
    """
    Open a bag (ROS 2 folder in sqlite3 or MCAP, whatever its name, or a ROS 1 ``.bag``)
    for its LaserScans.

    ``scan_topic`` is a topic, a list of them, or None for every LaserScan topic.

    Returns
    -------
    reader : rosbags AnyReader (open; close it)
    connections : the connections of the chosen LaserScan topics

    Raises
    ------
    BagError
        Missing or unreadable bag, no LaserScan topic, or an unknown ``scan_topic`` (the
        message lists the bag's).

    """
    p = Path(path)
    if not p.exists():
        raise BagError(f'input bag {p} does not exist')
    if p.is_file() and p.suffix != '.bag' and (p.parent / 'metadata.yaml').is_file():
        # a storage file of a ROS 2 bag: read the folder, whose metadata says how the files
        # are compressed and which others belong to the recording (split bags)
        p = p.parent
    if p.is_dir() and not (p / 'metadata.yaml').is_file():
        stored = sorted(f.name for f in p.iterdir() if f.suffix in ('.mcap', '.db3'))
        raise BagError(
            f'{p} is not a ROS 2 bag: the folder has no metadata.yaml' + (
                f' beside {", ".join(stored)} (a recording stopped before it closed? '
                f'`ros2 bag reindex {p}` writes it)' if stored else ''))
    try:
        reader = _open_reader(p)
    except Exception as err:  # rosbags raises several unrelated types for broken bags
        msg = f'cannot read bag {p}: {type(err).__name__}: {err}'
        raise BagError(msg) from err
    scans = [c for c in reader.connections if c.msgtype == SCAN_TYPE]
    topics = sorted({c.topic for c in scans})
    if not topics:
        others = sorted({f'{c.topic} ({c.msgtype})' for c in reader.connections})
        reader.close()
        raise BagError(f'no sensor_msgs/LaserScan topic in {p}; it has: {", ".join(others)}')
    chosen = topics
    if scan_topic is not None:
        asked = [scan_topic] if isinstance(scan_topic, str) else list(scan_topic)
        chosen = []
        for name in asked:
            want = {name, '/' + name.lstrip('/'), name.lstrip('/')}
            found = [t for t in topics if t in want]
            if not found:
                reader.close()
                raise BagError(f'--scan-topic {name!r} is not a LaserScan topic of {p}; '
                               f'choose one of: {", ".join(topics)}')
            chosen.append(found[0])
    return reader, [c for c in scans if c.topic in chosen]


STAGE_MARK = '.partial-'


def stage_path(out: Path, pid: int | None = None) -> Path:
    """The hidden staging folder of a bag written to ``out`` by process ``pid``."""
    return out.parent / f'.{out.name}{STAGE_MARK}{os.getpid() if pid is None else pid}'


def remove_stale_stages(out: Path) -> list[Path]:
    """
    Remove the staging folders of ``out`` that processes no longer running left behind
    (a replay killed with SIGKILL cannot clean up); return them, for the caller to say.
    """
    removed = []
    for stage in sorted(out.parent.glob(f'.{out.name}{STAGE_MARK}*')):
        pid = stage.name.rsplit(STAGE_MARK, 1)[1]
        if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        shutil.rmtree(stage, ignore_errors=True)
        removed.append(stage)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:             # someone else's process: running
        return True
    return True


def check_output(out: Path) -> None:
    """Refuse at once an output bag that exists or whose folder cannot be written in
    (BagError naming ``out``), before any work that would be lost."""
    if out.exists():
        raise BagError(f'output {out} exists; refusing to overwrite it')
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out.parent, prefix=f'.{out.name}.',
                                         suffix='.probe'):
            pass
    except OSError as err:
        msg = f'cannot write the output {out}: {err.strerror or err}'
        raise BagError(msg) from err


@contextmanager
def staged_bag(out: Path):
    """
    Yield the path to write a new bag folder at; it is moved to ``out`` when the block
    ends without an exception.

    rosbags names the storage file after the bag's folder, so the bag is written under
    ``out``'s own name inside a hidden staging folder beside it (``.OUT.partial-PID``)
    and the finished bag holds ``OUT.mcap``. An exception or an interruption in the
    block removes the staging folder and leaves nothing at ``out``, as does a Ctrl-C or
    SIGTERM that arrived in it (:mod:`stopping`) when its exception was lost on the way.
    Staging folders that dead processes left are removed first.

    Raises
    ------
    BagError
        When the folder of ``out`` cannot be written (the message names ``out``).
    """
    stage = stage_path(out)
    try:
        remove_stale_stages(out)
        if stage.exists():
            shutil.rmtree(stage)
        stage.mkdir(parents=True)
    except OSError as err:
        msg = f'cannot write the output {out}: {err.strerror or err}'
        raise BagError(msg) from err
    try:
        yield stage / out.name
        stopping.check()                 # a signal whose exception was lost: not moved
        os.replace(stage / out.name, out)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
