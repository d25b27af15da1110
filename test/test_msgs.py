"""extended_tracker_msgs: generated classes, a real DDS round trip, rosbags compatibility."""

from pathlib import Path
import time

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MSG_DIR = ROOT / 'interfaces' / 'extended_tracker_msgs' / 'msg'


def _filled_array():
    from extended_tracker_msgs.msg import ExtendedObject, ExtendedObjectArray

    arr = ExtendedObjectArray()
    arr.header.stamp.sec = 1700000000
    arr.header.stamp.nanosec = 123456789
    arr.header.frame_id = 'laser'
    for k in range(3):
        obj = ExtendedObject()
        obj.id = 2**40 + k
        obj.existence = 0.25 * (k + 1)
        obj.position.x, obj.position.y, obj.position.z = 1.5 + k, -2.25, 0.0
        obj.velocity.x, obj.velocity.y = 0.5, -0.125 * k
        obj.position_covariance = [0.01, 0.002, 0.002, 0.03]
        obj.extent = [0.09, 0.01, 0.01, 0.04 + k]
        obj.semi_major, obj.semi_minor, obj.orientation = 0.3, 0.2, 0.7 - k
        obj.length, obj.width = 1.2, 0.8
        obj.shape = ExtendedObject.SHAPE_RECTANGLE if k == 2 else ExtendedObject.SHAPE_ELLIPSE
        obj.measurement_rate = 7.5
        obj.num_detections = 11 + k
        obj.visibility = 0.5
        arr.objects.append(obj)
    arr.expected_count = 2.75
    arr.cardinality = [0.0, 0.05, 0.2, 0.7, 0.05]
    arr.num_detections = 36
    arr.processing_time = 0.00123
    return arr


def _assert_same(a, b):
    assert a.header.stamp.sec == b.header.stamp.sec
    assert a.header.stamp.nanosec == b.header.stamp.nanosec
    assert a.header.frame_id == b.header.frame_id
    assert len(a.objects) == len(b.objects)
    names = [
        'id', 'existence', 'semi_major', 'semi_minor', 'orientation', 'length', 'width',
        'shape', 'measurement_rate', 'num_detections', 'visibility',
    ]
    for oa, ob in zip(a.objects, b.objects):
        for n in names:
            assert getattr(oa, n) == getattr(ob, n), n
        assert (oa.position.x, oa.position.y, oa.position.z) == (
            ob.position.x, ob.position.y, ob.position.z)
        assert (oa.velocity.x, oa.velocity.y) == (ob.velocity.x, ob.velocity.y)
        np.testing.assert_array_equal(oa.position_covariance, ob.position_covariance)
        np.testing.assert_array_equal(oa.extent, ob.extent)
    np.testing.assert_array_equal(list(a.cardinality), list(b.cardinality))
    assert a.expected_count == b.expected_count
    assert a.num_detections == b.num_detections
    assert a.processing_time == b.processing_time


def test_constants_and_field_names():
    from extended_tracker_msgs.msg import ExtendedObject, ExtendedObjectArray

    assert ExtendedObject.SHAPE_ELLIPSE == 0 and ExtendedObject.SHAPE_RECTANGLE == 1
    expected = {
        'id', 'existence', 'position', 'velocity', 'position_covariance', 'extent',
        'semi_major', 'semi_minor', 'orientation', 'length', 'width', 'shape',
        'measurement_rate', 'num_detections', 'visibility',
    }
    assert expected <= set(ExtendedObject.get_fields_and_field_types())
    assert {'header', 'objects', 'expected_count', 'cardinality', 'num_detections',
            'processing_time'} <= set(ExtendedObjectArray.get_fields_and_field_types())


def test_in_process_publish_subscribe_round_trip():
    from extended_tracker_msgs.msg import ExtendedObjectArray
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        pub_node = rclpy.create_node('msgs_probe_pub', context=ctx)
        sub_node = rclpy.create_node('msgs_probe_sub', context=ctx)
        received = []
        sub_node.create_subscription(ExtendedObjectArray, 'probe_tracks', received.append, 10)
        pub = pub_node.create_publisher(ExtendedObjectArray, 'probe_tracks', 10)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(pub_node)
        executor.add_node(sub_node)
        sent = _filled_array()
        deadline = time.monotonic() + 10.0
        while not received and time.monotonic() < deadline:
            pub.publish(sent)
            executor.spin_once(timeout_sec=0.05)
        assert received, 'no message within 10 s on loopback'
        _assert_same(sent, received[0])
        executor.shutdown()
        pub_node.destroy_node()
        sub_node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_rosbags_custom_type_and_cdr_compatibility(tmp_path):
    from extended_tracker_msgs.msg import ExtendedObjectArray
    from rclpy.serialization import deserialize_message, serialize_message

    from extended_tracker.bag.bagio import message_typestore

    store = message_typestore()
    typename = 'extended_tracker_msgs/msg/ExtendedObjectArray'
    sent = _filled_array()
    raw = serialize_message(sent)
    decoded = store.deserialize_cdr(raw, typename)
    assert decoded.header.frame_id == 'laser'
    assert [o.id for o in decoded.objects] == [o.id for o in sent.objects]
    np.testing.assert_array_equal(decoded.cardinality, sent.cardinality)
    again = bytes(store.serialize_cdr(decoded, typename))
    # Byte equality is not required: CDR alignment padding is unspecified and rclpy leaves
    # it uninitialised. Same length and the same values decoded by rclpy are.
    assert len(again) == len(raw)
    _assert_same(sent, deserialize_message(again, ExtendedObjectArray))

    from rosbags.rosbag2 import Reader, StoragePlugin, Writer

    out = tmp_path / 'bag'
    with Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection('/tracks', typename, typestore=store)
        writer.write(conn, 42, again)
    with Reader(out) as reader:
        (conn,) = reader.connections
        assert conn.msgtype == typename
        (_, stamp, data) = next(iter(reader.messages()))
        assert stamp == 42
        back = store.deserialize_cdr(data, conn.msgtype)
        assert back.objects[2].shape == 1


@pytest.mark.parametrize('name', ['ExtendedObject', 'ExtendedObjectArray'])
def test_msg_files_exist(name):
    assert (MSG_DIR / f'{name}.msg').is_file()


def test_build_message_fills_defaults_converts_values_and_refuses_unknown_fields():
    """rosbags messages from plain data: a field left out takes its type's default (a
    fixed array its length of zeros), numpy scalars become the plain Python values the
    CDR writer takes, and a misspelt field is an error, not a silent default."""
    from extended_tracker.bag.bagio import build_message, message_typestore, SCAN_TYPE
    from extended_tracker.errors import BagError

    store = message_typestore()
    obj = build_message(store, 'extended_tracker_msgs/msg/ExtendedObject', {'id': np.uint64(7)})
    np.testing.assert_array_equal(obj.position_covariance, np.zeros(4))
    assert obj.extent.shape == (4,) and type(obj.id) is int and obj.id == 7
    assert (obj.position.x, obj.shape, obj.existence) == (0.0, 0, 0.0)
    assert type(obj.existence) is float and type(obj.shape) is int
    marker = build_message(store, 'visualization_msgs/msg/Marker',
                           {'frame_locked': np.bool_(True)})
    assert marker.frame_locked is True
    assert build_message(store, 'visualization_msgs/msg/Marker').frame_locked is False
    head = build_message(store, 'std_msgs/msg/Header',
                         {'frame_id': np.str_('laser'),
                          'stamp': {'sec': np.int64(3), 'nanosec': np.uint32(5)}})
    assert type(head.frame_id) is str and type(head.stamp.sec) is int
    scan = build_message(store, SCAN_TYPE, {'range_max': np.float32(13.5)})
    assert type(scan.range_max) is float and scan.range_max == 13.5
    store.serialize_cdr(obj, 'extended_tracker_msgs/msg/ExtendedObject')   # writable
    with pytest.raises(BagError, match=r"has no field\(s\) \['rangez'\]"):
        build_message(store, SCAN_TYPE, {'rangez': [1.0]})


def test_the_message_definitions_come_from_the_installed_share_folder(monkeypatch):
    """Installed, the package finds the definitions under the interpreter's prefix (as
    ament installs them) even without AMENT_PREFIX_PATH; the source tree comes last."""
    import sys

    from extended_tracker.bag.bagio import message_dirs

    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    dirs = message_dirs()
    assert dirs[0] == Path(sys.prefix) / 'share' / 'extended_tracker_msgs' / 'msg'
    assert dirs[-1] == ROOT / 'interfaces' / 'extended_tracker_msgs' / 'msg'


def test_a_prefix_with_only_some_message_definitions_is_passed_over(tmp_path, monkeypatch):
    """An ament prefix that holds one of the two .msg files (a half-removed install) is
    not where the definitions are read from: the next place that has both is."""
    from extended_tracker.bag.bagio import find_msg_definitions, MSG_PACKAGE

    partial = tmp_path / 'share' / MSG_PACKAGE / 'msg'
    partial.mkdir(parents=True)
    (partial / 'ExtendedObject.msg').write_text('float64 not_the_real_one\n')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    found = find_msg_definitions()
    assert found == {f'{MSG_PACKAGE}/msg/{n}': (MSG_DIR / f'{n}.msg').read_text()
                     for n in ('ExtendedObject', 'ExtendedObjectArray')}
