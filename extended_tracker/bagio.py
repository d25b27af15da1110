"""
Bag input and output with rosbags (no ROS installation needed).

The custom message types of ``extended_tracker_msgs`` are registered in a rosbags
typestore from their ``.msg`` definitions, so bags written here carry the definition and
``ros2 bag play`` on a Jazzy install can replay them.
"""

from __future__ import annotations

from functools import lru_cache
import os
from pathlib import Path
import sys

from .errors import BagError

MSG_PACKAGE = 'extended_tracker_msgs'
MSG_NAMES = ('ExtendedObject', 'ExtendedObjectArray')


def _msg_dirs() -> list[Path]:
    """Candidate ``msg`` folders: ament prefixes, this interpreter's prefix, the source tree."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    dirs = [Path(p) / 'share' / MSG_PACKAGE / 'msg' for p in prefixes]
    dirs.append(Path(__file__).resolve().parents[1] / 'interfaces' / MSG_PACKAGE / 'msg')
    return dirs


def find_msg_definitions() -> dict[str, str]:
    """
    Return the ``.msg`` texts of extended_tracker_msgs keyed by full type name.

    Raises
    ------
    BagError
        When no installed or source copy of the definitions is found.

    """
    for folder in _msg_dirs():
        if all((folder / f'{n}.msg').is_file() for n in MSG_NAMES):
            return {
                f'{MSG_PACKAGE}/msg/{n}': (folder / f'{n}.msg').read_text() for n in MSG_NAMES
            }
    searched = ', '.join(str(d) for d in _msg_dirs())
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
