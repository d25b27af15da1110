"""Bag replay: ROS 1 and ROS 2 inputs, topic choice, refusals, corrupt input, interruption."""

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from extended_tracker.bag.bagio import build_message, message_typestore, scan_data, SCAN_TYPE
from extended_tracker.bag.replay import replay
from extended_tracker.config import from_dict
from extended_tracker.errors import BagError
from extended_tracker.sim.laser import simulate, tutorial_scene

ROOT = Path(__file__).resolve().parents[1]
CFG = from_dict({'background': {'enabled': False}})


def sim_scans(seconds=2.0, seed=0):
    return [s for s, _ in simulate(tutorial_scene(), seconds, seed=seed)]


def write_ros2(path, topics=('/scan',), storage='sqlite3', seconds=2.0, zero_stamps=False,
               compression=None, edit=None, scans=None):
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    store = message_typestore()
    plugin = StoragePlugin.SQLITE3 if storage == 'sqlite3' else StoragePlugin.MCAP
    writer = Writer(path, version=9, storage_plugin=plugin)
    if compression:                            # ros2 bag record --compression-mode file|message
        writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with writer as w:
        conns = [w.add_connection(t, SCAN_TYPE, typestore=store) for t in topics]
        for k, scan in enumerate(scans or sim_scans(seconds)):
            ns = scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec
            data = scan_data(scan)
            if zero_stamps:                      # a driver that leaves the stamp unset
                data['header']['stamp'] = {'sec': 0, 'nanosec': 0}
            if edit:                             # edit(k, data): change the k-th scan
                edit(k, data)
            raw = store.serialize_cdr(build_message(store, SCAN_TYPE, data), SCAN_TYPE)
            for c in conns:
                w.write(c, ns, raw)


def write_ros1(path, seconds=2.0, compression=None, frame_id=None):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS1_NOETIC)
    writer = Writer(path)
    if compression:                            # rosbag record --bz2 | --lz4
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    with writer as w:
        conn = w.add_connection('/base_scan', 'sensor_msgs/msg/LaserScan', typestore=store)
        for k, scan in enumerate(sim_scans(seconds)):
            data = scan_data(scan)
            data['header']['seq'] = k
            if frame_id is not None:
                data['header']['frame_id'] = frame_id
            msg = build_message(store, 'sensor_msgs/msg/LaserScan', data)
            ns = scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec
            w.write(conn, ns, store.serialize_ros1(msg, 'sensor_msgs/msg/LaserScan'))


def read_output(path):
    from rosbags.rosbag2 import Reader

    # a finished bag: its storage file is named after the bag, nothing else beside it
    path = Path(path)
    assert sorted(f.name for f in path.iterdir()) == sorted([f'{path.name}.mcap', 'metadata.yaml'])
    assert f'- {path.name}.mcap' in (path / 'metadata.yaml').read_text()
    assert not list(path.parent.glob(f'.{path.name}.partial*'))
    store = message_typestore()
    out = {}
    with Reader(path) as r:
        conns = {c.topic: c for c in r.connections}
        assert set(conns) == {'/scan', '/tracks', '/tracks/markers'}
        # the custom definition is stored, so a Jazzy `ros2 bag play` can replay it
        assert 'MSG: extended_tracker_msgs/ExtendedObject' in conns['/tracks'].msgdef.data
        for c, t, raw in r.messages():
            msg = store.deserialize_cdr(raw, c.msgtype)
            out.setdefault(c.topic, []).append((t, msg))
    return out


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_ros2_inputs_both_storages(tmp_path, storage):
    write_ros2(tmp_path / 'in', storage=storage)
    s = replay(tmp_path / 'in', tmp_path / 'out', CFG, plot_path=tmp_path / 'run.png',
               progress=False)
    assert s.scans == 20 and s.topic == '/scan'
    out = read_output(tmp_path / 'out')
    assert len(out['/tracks']) == len(out['/tracks/markers']) == 20
    # bag time = scan stamp = header stamp
    t, msg = out['/tracks'][-1]
    assert t == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert len(msg.objects) >= 3
    assert (tmp_path / 'run.png').stat().st_size > 10_000
    assert_scans_copied(out['/scan'], sim_scans())


def assert_scans_copied(written, scans):
    """The output's /scan holds every input scan as it was, at its stamp."""
    assert len(written) == len(scans)
    for (t, got), want in zip(written, scans):
        assert t == want.header.stamp.sec * 10**9 + want.header.stamp.nanosec
        assert (got.header.stamp.sec, got.header.stamp.nanosec, got.header.frame_id) == (
            want.header.stamp.sec, want.header.stamp.nanosec, want.header.frame_id)
        for name in ('angle_min', 'angle_max', 'angle_increment', 'scan_time', 'range_min',
                     'range_max'):
            assert getattr(got, name) == np.float32(getattr(want, name)), name
        np.testing.assert_array_equal(got.ranges, np.asarray(want.ranges, np.float32))
        assert got.time_increment == 0.0 and len(got.intensities) == 0


def test_ros1_input(tmp_path):
    write_ros1(tmp_path / 'in.bag')
    s = replay(tmp_path / 'in.bag', tmp_path / 'out', CFG, progress=False)
    assert s.scans == 20 and s.topic == '/base_scan'
    out = read_output(tmp_path / 'out')
    assert len(out['/tracks']) == 20
    # a ROS 1 scan on /base_scan comes out as a ROS 2 scan on /scan, its seq left out
    assert_scans_copied(out['/scan'], sim_scans())


def strip_definitions(folder):
    """Make a sqlite3 bag written here look recorded on Humble: metadata version 5, no
    message definitions or type hashes (rosbag2 stored none before Iron)."""
    import re
    import sqlite3

    (db_path,) = Path(folder).glob('*.db3')
    db = sqlite3.connect(db_path)
    db.executescript("""
        DROP TABLE message_definitions;
        DROP TABLE metadata;
        CREATE TABLE old_topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                                serialization_format TEXT NOT NULL,
                                offered_qos_profiles TEXT NOT NULL);
        INSERT INTO old_topics SELECT id, name, type, serialization_format,
                                      offered_qos_profiles FROM topics;
        DROP TABLE topics;
        ALTER TABLE old_topics RENAME TO topics;
        UPDATE schema SET schema_version = 3, ros_distro = 'humble';
    """)
    db.commit()
    db.close()
    meta = Path(folder) / 'metadata.yaml'
    text = re.sub(r'\n\s*type_description_hash:\s*RIHS01_\w+', '', meta.read_text())
    text = text.replace('version: 9', 'version: 5').replace('  custom_data: null\n', '')
    assert 'RIHS01' not in text and 'version: 5' in text
    meta.write_text(text)


@pytest.mark.parametrize('kind', ['sqlite3 file', 'sqlite3 message', 'mcap file',
                                  'mcap message', 'ros1 bz2', 'ros1 lz4'])
def test_compressed_bags_replay(tmp_path, kind):
    """zstd-compressed ROS 2 bags (whole files or each message) and bz2/lz4 ROS 1 bags: the
    installed readers decompress them, and the scans come out as written."""
    storage, compression = kind.split()
    if storage == 'ros1':
        write_ros1(tmp_path / 'in.bag', compression=compression)
        src = tmp_path / 'in.bag'
        assert f'compression={compression}'.encode() in src.read_bytes()   # chunk headers
    else:
        write_ros2(tmp_path / 'in', storage=storage, compression=compression)
        src = tmp_path / 'in'
        assert f'compression_mode: {compression}' in (src / 'metadata.yaml').read_text()
    s = replay(src, tmp_path / 'out', CFG, progress=False)
    assert s.scans == 20
    assert_scans_copied(read_output(tmp_path / 'out')['/scan'], sim_scans())


@pytest.mark.parametrize('compression', [None, 'file', 'message'])
def test_a_ros2_bags_storage_file_reads_as_its_folder(tmp_path, compression):
    """Given the .mcap (or .mcap.zstd) inside a bag folder, the replay reads the folder:
    its metadata says how the messages are compressed (read alone, each message of a
    message-compressed bag failed to decode)."""
    write_ros2(tmp_path / 'in', storage='mcap', compression=compression)
    (storage_file,) = [f for f in (tmp_path / 'in').iterdir() if f.name != 'metadata.yaml']
    s = replay(storage_file, tmp_path / 'out', CFG, progress=False)
    assert s.scans == 20
    assert_scans_copied(read_output(tmp_path / 'out')['/scan'], sim_scans())


def test_a_bag_without_message_definitions_replays_as_with_them(tmp_path):
    """A Humble sqlite3 bag stores no definitions; its scans read as the Jazzy type."""
    write_ros2(tmp_path / 'jazzy')
    write_ros2(tmp_path / 'humble')
    strip_definitions(tmp_path / 'humble')
    a = replay(tmp_path / 'jazzy', tmp_path / 'out_jazzy', CFG, progress=False)
    b = replay(tmp_path / 'humble', tmp_path / 'out_humble', CFG, progress=False)
    assert b.scans == a.scans == 20 and b.distinct_ids == a.distinct_ids >= 3
    out_a, out_b = read_output(tmp_path / 'out_jazzy'), read_output(tmp_path / 'out_humble')
    assert_scans_copied(out_b['/scan'], sim_scans())
    for (ta, ma), (tb, mb) in zip(out_a['/tracks'], out_b['/tracks']):
        assert ta == tb
        assert [o.id for o in ma.objects] == [o.id for o in mb.objects]
        assert [(o.position.x, o.position.y) for o in ma.objects] == [
            (o.position.x, o.position.y) for o in mb.objects]


def test_a_ros2_folder_named_like_a_ros1_file_replays(tmp_path):
    """`ros2 bag record -o run.bag` makes a folder; the suffix does not make it ROS 1."""
    write_ros2(tmp_path / 'run.bag', storage='mcap')
    s = replay(tmp_path / 'run.bag', tmp_path / 'out.bag', CFG, progress=False)
    assert s.scans == 20 and s.topic == '/scan'
    assert_scans_copied(read_output(tmp_path / 'out.bag')['/scan'], sim_scans())
    # and the output, a ROS 2 folder named out.bag, replays in its turn
    again = replay(tmp_path / 'out.bag', tmp_path / 'again', CFG, progress=False)
    assert again.scans == 20


def test_a_ros1_frame_id_loses_its_leading_slash(tmp_path):
    """tf2 in ROS 2 refuses '/laser' (RViz2 shows nothing in it): the replay writes the
    scans, tracks and markers in 'laser', tracks them exactly as a bag in 'laser' is
    tracked, and says so in the summary."""
    write_ros1(tmp_path / 'slash.bag', frame_id='/laser')
    write_ros1(tmp_path / 'plain.bag', frame_id='laser')
    s = replay(tmp_path / 'slash.bag', tmp_path / 'out_slash', CFG, progress=False)
    plain = replay(tmp_path / 'plain.bag', tmp_path / 'out_plain', CFG, progress=False)
    assert s.renamed_frames == {'/laser': 'laser'} and plain.renamed_frames == {}
    assert "frame_id         '/laser' written as 'laser'" in '\n'.join(s.lines())
    out, want = read_output(tmp_path / 'out_slash'), read_output(tmp_path / 'out_plain')
    for topic in ('/scan', '/tracks'):
        assert {m.header.frame_id for _, m in out[topic]} == {'laser'}
    assert {m.header.frame_id for _, arr in out['/tracks/markers'] for m in arr.markers} \
        == {'laser'}
    for (_, a), (_, b) in zip(out['/tracks'], want['/tracks']):
        assert [(o.id, o.position.x, o.position.y) for o in a.objects] == [
            (o.id, o.position.x, o.position.y) for o in b.objects]


def test_a_topic_without_scans_is_refused(tmp_path):
    """A LaserScan topic declared but never written (a recording stopped at once): a
    clear error and no output, not a summary of 0 scans and an empty bag."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    with Writer(tmp_path / 'in', version=9, storage_plugin=StoragePlugin.MCAP) as w:
        w.add_connection('/scan', SCAN_TYPE, typestore=message_typestore())
    with pytest.raises(BagError, match='/scan in .* holds no scans'):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, plot_path=tmp_path / 'p.png',
               progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['in']


@pytest.mark.slow
def test_bundled_bag_replays():
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        s = replay(ROOT / 'bags' / 'demo', Path(d) / 'out', from_dict({}), progress=False)
    assert s.scans == 150
    # as bags/README.md gives them: A, B and C, all moving; the stretch of wall that a
    # person hid in the warm-up is learned as it is revealed (it was id 3, 14 scans)
    assert (s.distinct_ids, s.moving_ids) == (3, 3)


def test_topics_of_one_frame_are_one_scanner(tmp_path):
    """Two topics of one frame (a scanner published twice): one is tracked, the summary
    says which, and the output keeps the other's scans as read; --scan-topic picks
    another, and one the bag lacks is refused."""
    from rosbags.rosbag2 import Reader

    write_ros2(tmp_path / 'in', topics=('/front_scan', '/rear_scan'), seconds=1.0)
    s = replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    assert s.topic == '/front_scan' and s.scans == 10
    assert s.notes == ["/front_scan, /rear_scan share the frame 'laser': one scanner, "
                       '/front_scan taken (the most scans)']
    with Reader(tmp_path / 'out') as r:
        counts = {c.topic: c.msgcount for c in r.connections}
    assert counts['/scan'] == counts['/rear_scan'] == counts['/tracks'] == 10
    s = replay(tmp_path / 'in', tmp_path / 'out2', CFG, scan_topic='rear_scan', progress=False)
    assert s.topic == '/rear_scan' and s.scans == 10 and not s.notes
    with pytest.raises(BagError, match='choose one of'):
        replay(tmp_path / 'in', tmp_path / 'out3', CFG, scan_topic='/nope', progress=False)


def test_refuses_to_overwrite(tmp_path):
    write_ros2(tmp_path / 'in', seconds=0.5)
    (tmp_path / 'out').mkdir()
    with pytest.raises(BagError, match='refusing to overwrite'):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)


def test_corrupt_and_missing_inputs_give_clear_errors(tmp_path):
    with pytest.raises(BagError, match='does not exist'):
        replay(tmp_path / 'missing', tmp_path / 'out', CFG, progress=False)
    bad = tmp_path / 'bad.bag'
    bad.write_bytes(b'#ROSBAG V2.0\n' + b'\x00garbage' * 100)
    with pytest.raises(BagError, match='cannot read bag'):
        replay(bad, tmp_path / 'out', CFG, progress=False)
    write_ros2(tmp_path / 'in', storage='mcap', seconds=1.0)
    mcap = next((tmp_path / 'in').glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:2000])        # truncated file
    with pytest.raises(BagError):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    assert not (tmp_path / 'out').exists()
    # a bag folder whose metadata.yaml was never written (the recorder killed), and a
    # folder that is no bag: said so, not a rosbags FileNotFoundError
    (tmp_path / 'in' / 'metadata.yaml').unlink()
    with pytest.raises(BagError, match=r'no metadata.yaml beside in.mcap .*ros2 bag '
                                       r'reindex'):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    (tmp_path / 'notes').mkdir()
    with pytest.raises(BagError, match=r'notes is not a ROS 2 bag: the folder has no '
                                       r'metadata.yaml$'):
        replay(tmp_path / 'notes', tmp_path / 'out', CFG, progress=False)
    write_ros2(tmp_path / 'db', storage='sqlite3', seconds=0.5)      # the same for sqlite3
    (tmp_path / 'db' / 'metadata.yaml').unlink()
    with pytest.raises(BagError, match=r'no metadata.yaml beside db.db3 .*ros2 bag reindex'):
        replay(tmp_path / 'db', tmp_path / 'out', CFG, progress=False)


def test_a_ros1_bag_file_inside_a_ros2_bag_folder_is_read_as_itself(tmp_path):
    """A storage file named is read through its folder's metadata.yaml, but a ROS 1 .bag
    file is a whole recording: one kept inside a ROS 2 bag's folder is read, not the
    folder's bag."""
    from extended_tracker.bag.bagio import open_scans

    write_ros2(tmp_path / 'both', seconds=0.5)
    write_ros1(tmp_path / 'both' / 'old.bag', seconds=0.5)
    reader, conns = open_scans(tmp_path / 'both' / 'old.bag')
    reader.close()
    assert [c.topic for c in conns] == ['/base_scan']
    reader, conns = open_scans(next((tmp_path / 'both').glob('*.db3')))
    reader.close()
    assert [c.topic for c in conns] == ['/scan']
    assert not (tmp_path / 'out').exists()


def test_an_undecodable_scan_record_stops_with_its_topic(tmp_path):
    """A bag that opens, with a record on the LaserScan topic that is not a LaserScan:
    the replay stops with an error naming the topic, and leaves no output."""
    from rosbags.rosbag2 import Writer

    store = message_typestore()
    with Writer(tmp_path / 'in', version=9) as w:
        c = w.add_connection('/scan', SCAN_TYPE, typestore=store)
        scan = sim_scans(0.1)[0]
        w.write(c, 1, store.serialize_cdr(build_message(store, SCAN_TYPE, scan_data(scan)),
                                          SCAN_TYPE))
        w.write(c, 2, b'\x00\x01\x00\x00' + b'\xff' * 12)      # a CDR header, then junk
    with pytest.raises(BagError, match='cannot decode a sensor_msgs/msg/LaserScan on /scan'):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    assert not (tmp_path / 'out').exists() and not list(tmp_path.glob('.out.partial*'))


def test_progress_bar_on_a_terminal_only(tmp_path):
    import io

    from extended_tracker.bag.replay import _Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    tty = Terminal()
    bar = _Progress(4, tty)
    for done in range(1, 5):
        bar.update(done)                               # the last one always drawn
    bar.close()
    out = tty.getvalue()
    assert out.startswith('\r[#######') and out.endswith(f'\r[{"#" * 30}] 4/4 scans\n')
    pipe = io.StringIO()
    quiet = _Progress(4, pipe)
    quiet.update(4)
    quiet.close()
    assert pipe.getvalue() == ''


def test_no_laserscan_topic(tmp_path):
    from rosbags.rosbag2 import Writer

    store = message_typestore()
    with Writer(tmp_path / 'in', version=9) as w:
        c = w.add_connection('/chatter', 'std_msgs/msg/String', typestore=store)
        w.write(c, 1, store.serialize_cdr(build_message(store, 'std_msgs/msg/String',
                                                        {'data': 'x'}), 'std_msgs/msg/String'))
    with pytest.raises(BagError, match='no sensor_msgs/LaserScan topic.*/chatter'):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)


def test_interrupted_replay_leaves_no_bag(tmp_path, monkeypatch):
    import extended_tracker.bag.replay as rp

    write_ros2(tmp_path / 'in', seconds=2.0)
    real_step = rp.step
    calls = {'n': 0}

    def interrupted(state, scan, cfg, **kwargs):
        calls['n'] += 1
        if calls['n'] == 7:
            raise KeyboardInterrupt
        return real_step(state, scan, cfg, **kwargs)

    monkeypatch.setattr(rp, 'step', interrupted)
    with pytest.raises(KeyboardInterrupt):
        replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    assert not (tmp_path / 'out').exists()
    assert not list(tmp_path.glob('.out.partial*'))


def test_summary_gives_the_first_reason_of_each_event(tmp_path):
    """timing.max_gap under the bag's scan period: every scan but the first restarts
    the filter, and the summary says why in figures, once."""
    write_ros2(tmp_path / 'in')
    cfg = from_dict({'background': {'enabled': False}, 'timing': {'max_gap': 0.05}})
    s = replay(tmp_path / 'in', tmp_path / 'out', cfg, progress=False)
    assert s.events == {'time_gap': 19} and s.distinct_ids == 0
    assert s.lines()[-2:] == [
        'events           time_gap 19',
        '  first time_gap: 0.100 s since the previous scan, over timing.max_gap (0.05 s): '
        'tracks restarted']
    clean = replay(tmp_path / 'in', tmp_path / 'out2', CFG, progress=False)
    assert clean.lines()[-1] == 'events           none' and clean.distinct_ids >= 1


def test_the_summary_says_whether_and_from_which_scan_the_scans_showed_legs(tmp_path):
    """The tutorial's walkers at body height show no legs; at leg height the summary
    names the first scan whose diagnostics say ``legs``."""
    from extended_tracker.pipeline import PipelineState, step
    from extended_tracker.sim.leg_scenes import at_leg_height

    write_ros2(tmp_path / 'body')
    body = replay(tmp_path / 'body', tmp_path / 'out', CFG, progress=False)
    assert body.legs_from is None
    assert 'legs seen        no (a scanner at body height, or no one walked by)' in body.lines()
    scans = [s for s, _ in simulate(at_leg_height(tutorial_scene()), 2.0, seed=0)]
    write_ros2(tmp_path / 'legs', scans=scans)
    legs = replay(tmp_path / 'legs', tmp_path / 'out2', CFG, progress=False)
    state, flags = PipelineState.initial(CFG), []
    for scan in scans:
        state, res = step(state, scan, CFG)
        flags.append(res.diagnostics['legs'])
    assert legs.legs_from == flags.index(1) + 1
    assert (f'legs seen        from scan {legs.legs_from} on (a scanner at leg height: '
            'partition.leg_gap)') in legs.lines()


def test_zero_header_stamps_take_the_record_time(tmp_path):
    write_ros2(tmp_path / 'in', zero_stamps=True)
    s = replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    assert s.events == {'zero_stamp': 20} and s.distinct_ids >= 3
    assert s.first_reasons['zero_stamp'].startswith('the header stamp is zero')
    out = read_output(tmp_path / 'out')
    t, msg = out['/tracks'][-1]
    stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert t == stamp == 1_700_000_001_900_000_000          # the last record's time
    assert len(msg.objects) >= 3
    # the scans are written as read
    assert out['/scan'][-1][1].header.stamp.sec == 0


def test_the_summary_of_one_scan_and_of_none_gives_detections_per_scan():
    """Detections per scan divide by the scans, one included; with none there is no
    division by zero."""
    from extended_tracker.bag.replay import ReplaySummary

    assert 'valid detections 7 (7.0 per scan)' in ReplaySummary(scans=1,
                                                                valid_detections=7).lines()
    assert 'valid detections 0 (0.0 per scan)' in ReplaySummary().lines()


@pytest.mark.slow
def test_cli_replay_prints_a_summary(tmp_path):
    write_ros2(tmp_path / 'in', seconds=1.0)
    exe = Path(sys.executable).with_name('extended-tracker')
    done = subprocess.run([str(exe), 'replay', str(tmp_path / 'in'), '--output',
                           str(tmp_path / 'out'), '--quiet'], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'scans            10' in done.stdout and 'median' in done.stdout
    again = subprocess.run([str(exe), 'replay', str(tmp_path / 'in'), '--output',
                            str(tmp_path / 'out')], capture_output=True, text=True, timeout=120)
    assert again.returncode == 2 and 'refusing to overwrite' in again.stderr


@pytest.mark.parametrize('blocked', [False, True], ids=['', 'started-blocked'])
def test_sigterm_ends_a_command_as_ctrl_c_does(tmp_path, blocked):
    """A kill (SIGTERM: a supervisor, a CI timeout) stops `simulate` mid-way with a line
    and the status 128 + 15, its staging folder removed and nothing at OUTPUT (the next
    run is not refused). The same handler serves every command. Also when the parent
    started it with SIGTERM blocked (inherited across exec): it wrote its whole hour."""
    import signal
    import time

    from blocked import stops_blocked

    exe = Path(sys.executable).with_name('extended-tracker')
    argv = [str(exe), 'simulate', str(tmp_path / 'sim'), '--duration', '3600']
    proc = subprocess.Popen(stops_blocked(argv) if blocked else argv,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # wait until the bag is being written (its storage file inside the staging folder)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob('.sim.partial-*/sim/*.mcap')):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert (proc.returncode, out, err) == (143, '', 'extended-tracker: terminated\n')
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_goes_away_ends_a_command_quietly(tmp_path):
    """`extended-tracker ... | head`: stdout closed before the command prints. It ended
    with `error: [Errno 32] Broken pipe` and status 2; now quietly, with the status of a
    process SIGPIPE ends, the work done (the bag written) kept."""
    exe = Path(sys.executable).with_name('extended-tracker')
    proc = subprocess.Popen([str(exe), 'simulate', str(tmp_path / 'sim'), '--duration',
                             '0.5'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    proc.stdout.close()                                   # the reader is gone at once
    err = proc.stderr.read()
    assert (proc.wait(timeout=60), err) == (141, '')
    assert (tmp_path / 'sim' / 'truth.json').is_file()


def test_a_cleanup_failing_after_sigterm_still_ends_as_terminated(monkeypatch, capsys):
    """SIGTERM lands anywhere, a bag writer's close half way through a record among
    them; a cleanup that then fails replaces the exception: the command still ends with
    the line and status of a kill, and the SIGTERM handler before it is given back."""
    import os
    import signal
    import time

    from extended_tracker import cli

    def killed_mid_write(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(10)
        finally:
            raise RuntimeError('writer closed half a record')

    before = signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(cli, 'cmd_simulate', killed_mid_write)
    assert cli.main(['simulate', 'unused']) == 143
    assert capsys.readouterr().err == 'extended-tracker: terminated\n'
    assert signal.getsignal(signal.SIGTERM) is before
    # without a kill, the same failure is a bug and is not hidden
    monkeypatch.setattr(cli, 'cmd_simulate', lambda args: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        cli.main(['simulate', 'unused'])


#: the stop signals of the command line: each one's status and line
STOPS = {'SIGTERM': (143, 'extended-tracker: terminated\n'),
         'SIGINT': (130, 'extended-tracker: interrupted\n')}


@pytest.mark.parametrize('sig', ['SIGTERM', 'SIGINT'])
def test_a_signal_sent_while_blocked_ends_the_command_as_it_starts(sig, tmp_path, capsys):
    """Sent while the caller had it blocked: it arrives as the command takes the signals
    over, before any work (nothing at OUTPUT), and the caller's mask is given back."""
    import signal
    import threading

    from extended_tracker import cli

    signum = getattr(signal, sig)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, [signum])
    try:
        # to this thread alone: no other thread of the test process may take it
        signal.pthread_kill(threading.main_thread().ident, signum)
        assert cli.main(['simulate', str(tmp_path / 'out'), '--duration', '60']) == \
            STOPS[sig][0]
        assert signum in signal.pthread_sigmask(signal.SIG_BLOCK, [])
        assert signum not in signal.sigpending()
    finally:
        if signum in signal.sigpending():         # never taken: it would end pytest
            signal.sigtimedwait([signum], 0)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    assert capsys.readouterr() == ('', STOPS[sig][1])
    assert list(tmp_path.iterdir()) == []



def test_a_stop_is_the_first_signal_received_each_raising_its_own_exception():
    """SIGTERM raises ``Terminated``, SIGINT ``KeyboardInterrupt`` (code that catches a
    Ctrl-C does not swallow a kill); with both received, the first says why the command
    ends, and ``check`` raises that one again; after ``reset`` nothing is recorded."""
    import signal

    from extended_tracker import stopping

    stopping.reset()
    try:
        with pytest.raises(stopping.Terminated):
            stopping.on_signal(signal.SIGTERM, None)
        with pytest.raises(KeyboardInterrupt):
            stopping.on_signal(signal.SIGINT, None)
        assert stopping.received() == signal.SIGTERM
        with pytest.raises(stopping.Terminated):
            stopping.check()
    finally:
        stopping.reset()
    assert stopping.received() is None
    stopping.check()                                # nothing recorded: nothing raised
    assert not issubclass(stopping.Terminated, (KeyboardInterrupt, Exception))

def _lost_signal(sig='SIGTERM'):
    """Send this process ``sig`` inside code that swallows every exception, as C code
    may (an extension module's import did): the handler runs, its exception is lost."""
    import os
    import signal
    import time

    try:
        os.kill(os.getpid(), getattr(signal, sig))
        time.sleep(5)                             # the handler runs here and raises
    except BaseException:
        pass


@pytest.mark.parametrize('sig', STOPS)
@pytest.mark.parametrize('command', ['simulate', 'replay', 'results'])
def test_a_signal_whose_exception_is_lost_still_stops_the_command(command, sig, tmp_path,
                                                                   monkeypatch, capsys):
    """The handler's exception swallowed: the command still stops at the next scan, with
    the signal's line and status and nothing at OUTPUT (one SIGTERM in 30, and one SIGINT
    in 30, sent as simulate started its bag was lost in numpy.random's import, and the
    bag finished); `results` leaves the README as it was."""
    import signal

    from extended_tracker import cli
    import extended_tracker.bag.replay as replay_mod
    import extended_tracker.evaluation.evaluate as evaluate_mod
    from extended_tracker.sim import laser

    seen = []                                     # scans made (simulate) or tracked

    def lost_at_the_fourth():
        seen.append(1)
        if len(seen) == 4:
            _lost_signal(sig)

    if command == 'simulate':
        real = laser.simulated_scans

        def scans(*a):
            for item in real(*a):
                lost_at_the_fourth()
                yield item

        monkeypatch.setattr(laser, 'simulated_scans', scans)
        argv = ['simulate', str(tmp_path / 'out'), '--duration', '60']
    else:
        module = replay_mod if command == 'replay' else evaluate_mod
        real_step = module.step

        def step(*a, **k):
            lost_at_the_fourth()
            return real_step(*a, **k)

        monkeypatch.setattr(module, 'step', step)
        if command == 'replay':
            write_ros2(tmp_path / 'in', seconds=6.0)
            argv = ['replay', str(tmp_path / 'in'), '--output', str(tmp_path / 'out'),
                    '--quiet']
        else:
            readme = (ROOT / 'doc' / 'results.md').read_text()
            (tmp_path / 'in').write_text(readme)
            argv = ['results', '--readme', str(tmp_path / 'in')]
    before = {s: signal.getsignal(getattr(signal, s)) for s in STOPS}
    status, line = STOPS[sig]
    assert cli.main(argv) == status
    assert capsys.readouterr() == ('', line)
    assert len(seen) == 4                         # stopped at the next scan, not the end
    assert [p.name for p in tmp_path.iterdir()] == ([] if command == 'simulate' else ['in'])
    if command == 'results':
        assert (tmp_path / 'in').read_text() == readme
    assert {s: signal.getsignal(getattr(signal, s)) for s in STOPS} == before


@pytest.mark.parametrize('sig', STOPS)
@pytest.mark.parametrize('where', ['printing', 'bag_finished'])
def test_a_signal_lost_outside_the_scan_loops_still_ends_the_command(where, sig, tmp_path,
                                                                     monkeypatch, capsys):
    """Lost where no scan loop looks for it: in a command that only prints, the end of
    the command sees it; while a finished bag is closed or its truth written, the bag is
    not moved into place. Either way the signal's status and line, not 0."""
    from extended_tracker import cli, stopping
    from extended_tracker.bag.bagio import staged_bag

    def lost(args):
        if where == 'printing':
            _lost_signal(sig)
        else:
            with staged_bag(tmp_path / 'out') as tmp:
                tmp.mkdir()
                (tmp / 'truth.json').write_text('{}')
                _lost_signal(sig)
        return 0

    monkeypatch.setattr(cli, 'cmd_simulate', lost)
    status, line = STOPS[sig]
    assert cli.main(['simulate', 'unused']) == status
    assert capsys.readouterr().err == line
    assert list(tmp_path.iterdir()) == []
    # the signal is the command's own: what runs after it (a library call writing a
    # bag, the next command) does not see it
    assert stopping.received() is None
    stopping.check()
    monkeypatch.setattr(cli, 'cmd_simulate', lambda args: 0)
    assert cli.main(['simulate', 'unused']) == 0


def test_plot_paths_get_their_folder_or_a_one_line_error(tmp_path, capsys):
    """--plot in a folder not made yet: made, as the output bag's is. A plot path that
    cannot be made (its folder is a file): a one-line error before any work, no bag."""
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=1.0)
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'), '--plot',
                 str(tmp_path / 'new' / 'deeper' / 'run.png')]) == 0
    assert (tmp_path / 'new' / 'deeper' / 'run.png').stat().st_size > 10_000
    capsys.readouterr()
    (tmp_path / 'file').write_text('not a folder')
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out2'), '--plot',
                 str(tmp_path / 'file' / 'run.png')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('extended-tracker: error: ') and str(tmp_path / 'file') in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / 'out2').exists()


@pytest.mark.parametrize('name, why', [('folder', 'is a folder: name an image file'),
                                       ('run.xyz', "'.xyz' is not an image format"),
                                       ('run.pgf', "'.pgf' is not an image format")])
def test_a_plot_name_no_picture_can_have_is_refused_before_the_replay(tmp_path, capsys,
                                                                       monkeypatch, name,
                                                                       why):
    """A folder, or a suffix savefig cannot write (pgf needs LaTeX): a one-line error
    before a scan is read, no bag; these ended a whole replay in savefig's traceback."""
    import extended_tracker.bag.replay as replay_mod
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    (tmp_path / 'folder').mkdir()
    monkeypatch.setattr(replay_mod, 'open_scans', lambda *a: pytest.fail('the bag was read'))
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'), '--plot',
                 str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'extended-tracker: error: plot {tmp_path / name}') and why in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / 'out').exists()


def test_a_plot_name_without_a_suffix_is_written_as_png_and_said_so(tmp_path, capsys):
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'), '--quiet',
                 '--plot', str(tmp_path / 'run')]) == 0
    assert f'plot             {tmp_path / "run.png"}\n' in capsys.readouterr().out
    assert (tmp_path / 'run.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert not (tmp_path / 'run').exists()
    # another format by its suffix, any case
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out2'), '--quiet',
                 '--plot', str(tmp_path / 'run.SVG')]) == 0
    assert (tmp_path / 'run.SVG').read_text().lstrip().startswith('<?xml')


def test_cli_replay_with_a_preset(tmp_path, capsys):
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'),
                 '--preset', 'leg_height', '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'scans            5' in out
    # where the bag went; no plot line when no --plot was asked for
    assert out.endswith(f'output bag       {tmp_path / "out"}\n') and '\nplot ' not in out
    cfg = tmp_path / 'c.yaml'
    cfg.write_text('model: {mode: phd}\n')
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'o2'), '--config',
                 str(cfg), '--preset', 'leg_height', '--quiet']) == 2
    assert '--config or --preset, not both' in capsys.readouterr().err
    assert not (tmp_path / 'o2').exists()


def test_cli_refuses_an_option_it_does_not_have(tmp_path, capsys):
    """An option no command has (a typo of --quiet) is refused with argparse's usage error
    before anything runs; only bench passes unknown options on, to its own parser."""
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    with pytest.raises(SystemExit) as stop:
        main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'), '--quite'])
    assert stop.value.code == 2
    assert 'unrecognized arguments: --quite' in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


@pytest.mark.slow
def test_real_replays_every_folder_with_a_line_each(tmp_path, capsys):
    """`extended-tracker real` on a folder of recordings: one line of figures per bag, its
    PNG and output bag, and a bag's events under its line with the first reason."""
    from extended_tracker.cli import main

    data = tmp_path / 'real'
    data.mkdir()
    write_ros2(data / 'a_plain')
    write_ros2(data / 'b_unstamped', zero_stamps=True)
    assert main(['real', '--data', str(data), '--out', str(tmp_path / 'out')]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:3] == ['bag', 'scans', 'det/scan']
    plain, unstamped = lines[1].split(), lines[2].split()
    assert plain[0] == 'a_plain' and plain[1] == '20' and plain[-1] == 'defaults'
    # det/scan: the returns inside [range_min, range_max) per scan, counted off the scans
    returns = [np.count_nonzero((np.asarray(s.ranges) >= s.range_min)
                                & (np.asarray(s.ranges) < s.range_max)) for s in sim_scans()]
    assert plain[2] == f'{np.mean(returns):.1f}', (plain, np.mean(returns))
    assert unstamped[0] == 'b_unstamped' and unstamped[1:6] == plain[1:6]   # same tracks
    assert lines[3].startswith('  zero_stamp 20 (first: the header stamp is zero')
    assert lines[4] == f'bags and PNGs in {tmp_path / "out"}'
    for name in ('a_plain', 'b_unstamped'):
        assert (tmp_path / 'out' / f'{name}.png').stat().st_size > 10_000
        assert (tmp_path / 'out' / f'{name}_tracks').is_dir()


def test_real_on_one_bag_replays_it_and_on_no_bags_says_so(tmp_path, capsys):
    """`real --data` naming a bag itself (folder or ROS 1 file) replays that bag; a folder
    without bags, or no folder, is said to hold none (status 0: `make real` without
    ../shared is not an error)."""
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'one')
    write_ros1(tmp_path / 'two.bag')
    (tmp_path / 'empty').mkdir()
    for data, label in (('one', 'one'), ('two.bag', 'two')):
        assert main(['real', '--data', str(tmp_path / data),
                     '--out', str(tmp_path / f'out_{label}')]) == 0
        lines = capsys.readouterr().out.splitlines()
        assert lines[1].split()[:2] == [label, '20'], lines
        assert (tmp_path / f'out_{label}' / f'{label}.png').is_file()
    (tmp_path / 'notes.txt').write_text('not a recording')
    for data in ('empty', 'notes.txt'):       # a folder without bags; a file not a .bag
        assert main(['real', '--data', str(tmp_path / data), '--out',
                     str(tmp_path / 'out_none')]) == 0
        captured = capsys.readouterr()
        assert 'no recordings at' in captured.err and not captured.out
    # a path that is not there (a typo) is an error, not an empty folder
    assert main(['real', '--data', str(tmp_path / 'missing'), '--out',
                 str(tmp_path / 'out_none')]) == 2
    captured = capsys.readouterr()
    assert captured.err == f'extended-tracker: error: --data {tmp_path / "missing"} does ' \
                           'not exist\n' and not captured.out
    assert not (tmp_path / 'out_none').exists()


@pytest.mark.slow
@pytest.mark.parametrize('out_name', ['.', 'out'])
def test_real_run_again_with_its_output_in_the_data_folder_replays_only_recordings(
        tmp_path, capsys, out_name):
    """--out the --data folder itself, or a folder inside it: a second run skips the
    first run's output bags with a line each (they hold the tracks) and the --out
    folder, instead of replaying them into NAME_tracks_tracks or failing on the PNG
    folder as a broken bag."""
    from extended_tracker.cli import main

    data = tmp_path / 'data'
    write_ros2(data / 'one', seconds=1.0)
    out = data / out_name
    for run in (1, 2):
        assert main(['real', '--data', str(data), '--out', str(out)]) == 0
        lines = capsys.readouterr().out.splitlines()
        assert lines[1].split()[:2] == ['one', '10'], lines
        if run == 2 and out_name == '.':
            assert lines[2] == f'{"one_tracks":48s} skipped: a replay output (it holds ' \
                               'tracks), not a recording'
            assert len(lines) == 4
        else:                    # the --out folder inside --data is no candidate
            assert len(lines) == 3 and lines[2].startswith('bags and PNGs in')
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ['one.png', 'one_tracks'] + (['one'] if out_name == '.' else []))


@pytest.mark.slow
def test_real_goes_on_past_a_folder_it_cannot_replay(tmp_path, capsys):
    """A folder that is no bag (or a broken one) gets a line saying why; the bags after it
    (folders, and ROS 1 files beside them) are still replayed, and the exit status says
    something failed."""
    from extended_tracker.cli import main

    data = tmp_path / 'real'
    (data / 'a_notes').mkdir(parents=True)
    (data / 'a_notes' / 'README.txt').write_text('not a bag')
    write_ros1(data / 'b_ros1.bag', frame_id='/laser')
    write_ros2(data / 'c_plain')
    assert main(['real', '--data', str(data), '--out', str(tmp_path / 'out')]) == 1
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert lines[1].startswith('a_notes') and 'not replayed: ' in lines[1]
    assert lines[2].split()[0] == 'b_ros1' and lines[2].split()[1] == '20'
    assert lines[3] == "  frame_id '/laser' written as 'laser'"
    assert lines[4].split()[:2] == ['c_plain', '20']
    assert '1 of 3 not replayed' in captured.err
    assert (tmp_path / 'out' / 'c_plain.png').is_file()
    assert not (tmp_path / 'out' / 'a_notes_tracks').exists()


def test_real_replays_a_bag_whose_metadata_it_cannot_read_instead_of_skipping_it(
        tmp_path, capsys, monkeypatch):
    """Whether a folder is an earlier run's output is read off its metadata.yaml; one that
    cannot be read is not known to be an output, so it is tried as a recording and its
    line says why it failed (the reader cannot read it either), instead of the folder
    being passed over as tracks."""
    from extended_tracker.cli import main

    data = tmp_path / 'real'
    write_ros2(data / 'locked', seconds=0.5)
    meta = data / 'locked' / 'metadata.yaml'
    read_text = Path.read_text

    def refuse(self, *args, **kwargs):
        if self == meta:
            raise PermissionError(13, 'Permission denied', str(self))
        return read_text(self, *args, **kwargs)

    monkeypatch.setattr(Path, 'read_text', refuse)
    assert main(['real', '--data', str(data), '--out', str(tmp_path / 'out')]) == 1
    line = capsys.readouterr().out.splitlines()[1]
    assert line.startswith(f'{"locked":48s} not replayed: ') and 'Permission denied' in line


def test_the_summary_is_made_of_the_results_it_replays(tmp_path, monkeypatch):
    """Every figure of the summary against the step results of the replay, recomputed
    here: the times set to 1, 2, ... ms scan by scan (median and p99 known), and two
    events of one kind whose reasons differ (the first is kept). Three ids are added to
    some scans' estimates: one that strays 0.7 m and comes back (not moving), one that
    goes exactly 1 m (not more: not moving), one that goes 1.5 m and comes back (moving:
    the farthest it got counts, not where it ended); with them the most objects of a scan
    are not the last scan's."""
    from dataclasses import fields

    import extended_tracker.bag.replay as rp
    from extended_tracker.tracks.estimates import Estimates

    from mixtures import estimates

    real, seen = rp.step, []
    added = {901: {20: 0.0, 21: 0.7, 22: 0.0}, 902: {20: 0.0, 21: 1.5, 22: 0.0},
             903: {20: 0.0, 21: 1.0}}

    def with_object(e, label, x):
        one = estimates([label], [[x, -5.0]])
        return Estimates(*(np.concatenate([getattr(e, f.name), getattr(one, f.name)])
                           for f in fields(Estimates)))

    def step(*args, **kwargs):
        state, res = real(*args, **kwargs)
        seen.append(res)
        res.processing_time = len(seen) * 1e-3
        if len(seen) in (5, 9):
            res.event, res.error = 'time_gap', f'reason {len(seen)}'
        for label, path in added.items():
            if len(seen) in path:
                res.estimates = with_object(res.estimates, label, path[len(seen)])
                res.age, res.since_detected, res.kind_confidence = (
                    np.append(a, 0.0) for a in (res.age, res.since_detected,
                                                res.kind_confidence))
                res.motion, res.kind = (np.append(a, 0).astype(np.uint8)
                                        for a in (res.motion, res.kind))
        return state, res

    monkeypatch.setattr(rp, 'step', step)
    write_ros2(tmp_path / 'in', seconds=6.0)
    s = replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    n = len(seen)
    counts = [len(r.estimates) for r in seen]
    first, travel = {}, {}
    for r in seen:
        for lab, xy in zip(r.estimates.label.tolist(), r.estimates.m[:, :2]):
            first.setdefault(lab, xy)
            travel[lab] = max(travel.get(lab, 0.0), float(np.hypot(*(xy - first[lab]))))
    assert s.scans == n == 60
    assert s.valid_detections == sum(r.diagnostics['detections'] for r in seen)
    assert s.distinct_ids == len(travel) >= 3
    assert s.moving_ids == sum(v > 1.0 for v in travel.values()) >= 1
    assert travel[901] == pytest.approx(0.7) and travel[902] == pytest.approx(1.5)
    assert travel[903] == 1.0
    assert s.mean_count == pytest.approx(sum(counts) / n)
    assert s.max_count == max(counts) > counts[-1]
    assert (f'valid detections {s.valid_detections} '
            f'({s.valid_detections / n:.1f} per scan)') in s.lines()
    assert s.median_ms == pytest.approx((n + 1) / 2)
    assert s.p99_ms == pytest.approx(1 + 0.99 * (n - 1))
    assert s.events == {'time_gap': 2} and s.first_reasons == {'time_gap': 'reason 5'}


def test_the_plot_shows_the_field_of_view_of_the_first_readable_scan(tmp_path, monkeypatch):
    """The sector drawn is that of the scans: from angle_min to its last beam (not one
    beyond), out to range_max, taken from the first scan that is not malformed."""
    import extended_tracker.report.plotting as plotting

    drawn = {}
    monkeypatch.setattr(plotting, 'plot_run', lambda sketch, path, title='', fov=None:
                        drawn.setdefault('fov', fov))

    def malformed_first(k, data):
        if k == 0:
            data['angle_increment'] = 0.0

    write_ros2(tmp_path / 'in', edit=malformed_first)
    s = replay(tmp_path / 'in', tmp_path / 'out', CFG, plot_path=tmp_path / 'run.png',
               progress=False)
    assert s.events == {'malformed_scan': 1}
    scan = sim_scans(0.1)[0]
    last = scan.angle_min + scan.angle_increment * (len(scan.ranges) - 1)
    assert list(drawn['fov']) == ['']                     # one scanner, in its own frame
    assert drawn['fov'][''] == pytest.approx((scan.angle_min, last, scan.range_max))
    assert last == pytest.approx(np.pi / 2)


def test_fov_and_frame_names_at_their_edges():
    from extended_tracker.bag.replay import ros2_frame_id, scan_fov

    scan = sim_scans(0.1)[0]
    scan.range_max = float('inf')            # no range to draw the sector out to
    assert scan_fov(scan) is None
    scan.range_max, scan.angle_increment = 5.0, -scan.angle_increment   # clockwise beams
    assert scan_fov(scan) == pytest.approx((-1.5 * np.pi, -np.pi / 2, 5.0))
    assert [ros2_frame_id(f) for f in ('/laser', '//base/laser', 'laser', '/')] == [
        'laser', 'base/laser', 'laser', '/']


def test_scans_are_copied_with_their_intensities_and_time_increment(tmp_path):
    """A driver's intensities and time between beams reach the output's /scan as read
    (the simulated scans carry neither, so the other tests could not tell)."""
    def with_intensities(k, data):
        data['time_increment'] = 1.25e-5
        data['intensities'] = np.arange(len(data['ranges']), dtype=np.float32) + k

    write_ros2(tmp_path / 'in', seconds=0.5, edit=with_intensities)
    replay(tmp_path / 'in', tmp_path / 'out', CFG, progress=False)
    out = read_output(tmp_path / 'out')['/scan']
    assert len(out) == 5
    for k, (_, scan) in enumerate(out):
        assert scan.time_increment == np.float32(1.25e-5)
        np.testing.assert_array_equal(scan.intensities, np.arange(361, dtype=np.float32) + k)


def test_a_stale_staging_folder_of_the_same_name_is_cleared(tmp_path):
    """A staging folder left by an earlier process of the same pid (the pid reused after a
    kill -9) is removed first: the new bag is written, with nothing of the old in it."""
    import os

    from extended_tracker.bag.bagio import staged_bag

    out = tmp_path / 'out'
    stale = tmp_path / f'.out.partial-{os.getpid()}'
    (stale / 'out').mkdir(parents=True)
    (stale / 'out' / 'old.mcap').write_text('junk')
    with staged_bag(out) as tmp:
        tmp.mkdir()
        (tmp / 'new.mcap').write_text('bag')
    assert sorted(p.name for p in out.iterdir()) == ['new.mcap']
    assert not stale.exists()


@pytest.mark.slow
def test_real_with_a_config_replays_every_bag_with_it_and_one_replay_output_by_name(
        tmp_path, capsys, monkeypatch):
    """`real --config` uses that config for every bag, the leg-height ones included (its
    line says --config); `real --data` naming one earlier replay's output replays it (the
    skip is for such bags met inside a folder)."""
    import extended_tracker.bag.replay as rp
    from extended_tracker.cli import main
    from extended_tracker.configio import load_yaml

    used = []
    real_replay = rp.replay
    monkeypatch.setattr(rp, 'replay', lambda bag, target, cfg, *a, **k:
                        used.append(cfg) or real_replay(bag, target, cfg, *a, **k))
    data = tmp_path / 'data'
    write_ros2(data / 'legtracker_positive_1', seconds=1.0)   # a leg-height name
    config = tmp_path / 'phd.yaml'
    config.write_text('model: {mode: phd}\n')
    assert main(['real', '--data', str(data), '--out', str(tmp_path / 'out'),
                 '--config', str(config)]) == 0
    line = capsys.readouterr().out.splitlines()[1]
    assert line.split()[0] == 'legtracker_positive_1' and line.endswith('--config')
    assert used == [load_yaml(config)]
    tracks = tmp_path / 'out' / 'legtracker_positive_1_tracks'
    assert main(['real', '--data', str(tracks), '--out', str(tmp_path / 'again')]) == 0
    line = capsys.readouterr().out.splitlines()[1]
    assert line.split()[:2] == ['legtracker_positive_1_tracks', '10'], line


# nobody, root included, can create a file under /proc: an unwritable place on any machine
UNWRITABLE = Path('/proc')


def test_an_unwritable_plot_or_output_is_refused_before_any_work(tmp_path, capsys,
                                                                  monkeypatch):
    """A --plot or an output in a folder that cannot be written: a one-line error that
    names the path given (not a staging folder), before a scan is read; no bag left to
    make a rerun refuse."""
    import extended_tracker.bag.replay as replay_mod
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    monkeypatch.setattr(replay_mod, 'open_scans', lambda *a: pytest.fail('the bag was read'))
    plot = UNWRITABLE / 'run.png'
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out'), '--plot',
                 str(plot)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'extended-tracker: error: plot {plot}: cannot write there')
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / 'out').exists()
    out = UNWRITABLE / 'tracks'
    assert main(['replay', str(tmp_path / 'in'), '-o', str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'extended-tracker: error: cannot write the output {out}: ')
    assert '.partial' not in err and len(err.strip().splitlines()) == 1


def test_a_staging_folder_left_by_a_killed_run_is_removed_and_said(tmp_path, capsys):
    """A replay killed with SIGKILL cannot clean up its hidden staging folder: the next
    run into the same output removes it and says so. One of a process still running is
    another run's, and stays."""
    from extended_tracker.bag.bagio import stage_path
    from extended_tracker.cli import main

    write_ros2(tmp_path / 'in', seconds=0.5)
    gone = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                          capture_output=True, text=True, check=True)
    dead = stage_path(tmp_path / 'out', int(gone.stdout))
    (dead / 'out').mkdir(parents=True)
    live = stage_path(tmp_path / 'out', 1)                # init: always running
    live.mkdir()
    assert main(['replay', str(tmp_path / 'in'), '-o', str(tmp_path / 'out')]) == 0
    out = capsys.readouterr().out
    assert f'removed          {dead} (the staging folder of an earlier run' in out
    assert not dead.exists() and live.exists() and (tmp_path / 'out').is_dir()
