"""The node's event log and scan-gap counter (ros/events.py: plain Python, no ROS)."""

from extended_tracker.ros.events import EventLog, Pace, reason_kind, ScanGaps

MS = 1_000_000


def test_reasons_that_differ_only_in_figures_are_one_kind():
    assert reason_kind('2.500 s since the previous scan, over 2 s') == reason_kind(
        '31.25 s since the previous scan, over 2 s')
    assert reason_kind('len(ranges) = 0 disagrees') != reason_kind('angle_increment is zero')


def test_a_new_kind_of_reason_is_said_at_once_and_the_rest_in_the_summary():
    log = EventLog()
    assert log.record('malformed_scan', 'a: 1').endswith('(counted; further ones are '
                                                         'summarised every 10 s)')
    assert log.record('malformed_scan', 'a: 2') is None
    assert log.record('malformed_scan', 'b') == 'malformed_scan: b (3 so far)'
    assert log.record('time_gap', 'gap 3').startswith('time_gap: gap 3')
    assert log.summary_lines() == [
        'malformed_scan: 1 more since the last summary (3 in all); last: b']
    assert log.summary_lines() == []
    assert log.counts == {'malformed_scan': 3, 'time_gap': 1}


def test_the_scanners_period_comes_from_scan_time_or_the_shortest_step():
    gaps = ScanGaps()
    stamps = [0, 25, 50, 75, 175, 200]                      # 3 missing before 175
    assert [gaps.missing(t * MS, 0.025) for t in stamps] == [0, 0, 0, 0, 3, 0]
    # no scan_time, a burst the queue thinned: most steps are long, the shortest is the
    # period (here after the first three steps are known)
    gaps = ScanGaps()
    got = [gaps.missing(t * MS) for t in (0, 25, 1000, 1025, 2000, 2050)]
    assert got == [0, 0, 0, 0, 38, 1] and gaps.total == 39
    # repeats and steps back are not gaps
    assert gaps.missing(2050 * MS) == 0 and gaps.missing(10 * MS) == 0


def test_pace_says_the_period_at_the_nth_slow_scan_in_a_row_and_counts_again():
    """Three slow scans in a row (10 Hz stamps, 0.15 s each) give the period at the
    third; a scan that kept up, or a stamp that goes back, starts the count again."""
    pace = Pace(3)
    stamp = [0]

    def scan(took, step=100):
        stamp[0] += step * MS
        return pace.falling_behind(stamp[0], took)

    assert pace.falling_behind(0, 0.5) is None               # no period yet
    assert [scan(0.15) for _ in range(3)] == [None, None, 0.1]
    assert [scan(0.15), scan(0.05), scan(0.15), scan(0.15)] == [None, None, None, None]
    assert scan(0.15, step=-50) is None                      # back in time: no period
    assert [scan(0.15) for _ in range(3)] == [None, None, 0.1]
