"""scripts/soak_table.py: a stream soak's frames binned by minute, the percentiles and the
verdict, on synthetic rows."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
import soak_table as st

T0 = 1_700_000_000.0


def stream(minutes: float, rate: float, answered_every: int = 1, status: str = "ok"):
    """Frames sent at `rate` for `minutes`: every `answered_every`-th answered (latency = its
    index in the minute, ms), the others dropped."""
    frames = []
    for i in range(int(minutes * 60 * rate)):
        t = T0 + i / rate
        if i % answered_every == 0:
            frames.append(st.Frame(t, t + 0.1, status, latency_ms=float(i % 100 + 1)))
        else:
            frames.append(st.Frame(t, t + 0.05, "dropped"))
    return frames


def flat_rss(minutes: float, mib: float, slope_mib_per_min: float = 0.0):
    """A sample every 5 s, RSS rising by `slope_mib_per_min`; no CPU recorded."""
    return [
        st.Sample(T0 + s, mib + slope_mib_per_min * s / 60)
        for s in range(0, int(minutes * 60) + 5, 5)
    ]


def test_percentiles_are_nearest_rank():
    values = [float(v) for v in range(1, 101)]
    assert st.percentile(values, 50) == 50.0
    assert st.percentile(values, 90) == 90.0
    assert st.percentile(values, 99) == 99.0
    # One slow value in a hundred sets the max, not the p99.
    assert st.percentile([*[1.0] * 99, 500.0], 99) == 1.0
    assert st.percentile([7.0], 50) == 7.0
    assert st.percentile([3.0, 1.0, 2.0], 100) == 3.0


def test_frames_fall_into_minutes_by_send_time_and_a_short_tail_is_partial():
    frames = stream(3.1, 10, answered_every=2)
    minutes = st.bin_minutes(frames, flat_rss(3.1, 400.0))
    assert [m.index for m in minutes] == [1, 2, 3, 4]
    assert [m.whole for m in minutes] == [True, True, True, False]
    assert [m.sent for m in minutes[:3]] == [600, 600, 600]
    assert minutes[0].answered == 300 and minutes[0].dropped == 300
    assert minutes[0].answered_per_s == pytest.approx(5.0)
    assert minutes[3].sent == 60
    assert minutes[3].seconds == pytest.approx(5.9)
    assert minutes[0].rss_mib == pytest.approx(400.0)
    assert sum(m.errors for m in minutes) == 0


def test_a_minute_whose_last_send_is_within_the_slack_of_its_end_is_whole():
    # 15/s for exactly 120 s: the last send is 1/15 s before the end.
    minutes = st.bin_minutes(stream(2, 15), flat_rss(2, 300.0))
    assert [m.whole for m in minutes] == [True, True]
    assert minutes[1].answered_per_s == pytest.approx(15.0)


def test_rows_without_a_send_time_go_by_receive_time_and_count_as_errors():
    frames = stream(2, 5)
    frames.append(st.Frame(None, T0 + 90.0, "lost:timed_out"))
    frames.append(st.Frame(T0 + 10.0, T0 + 10.2, "error:bad_image"))
    minutes = st.bin_minutes(frames, [])
    assert [m.errors for m in minutes] == [1, 1]
    assert minutes[0].rss_mib is None
    checks = {c.name: c for c in st.verdict(minutes)}
    assert checks["errors"].passed is False
    assert checks["RSS"].passed is None


def test_verdict_passes_a_steady_run():
    minutes = st.bin_minutes(stream(10, 15, answered_every=3), flat_rss(10, 420.0, 0.5))
    checks = st.verdict(minutes)
    assert [c.passed for c in checks] == [True, True, True]
    text = st.report(minutes, checks)
    assert "Verdict: PASS" in text
    assert text.count("\n| ") == 11  # the header's separator and ten minutes


def test_verdict_fails_a_falling_rate_and_growing_memory():
    first = stream(1, 10)
    second = [st.Frame(f.send_s + 60, f.receive_s + 60, "ok", 5.0) for f in stream(1, 10)]
    # The last minute answers one frame in two: 5/s against 10/s.
    last = [
        st.Frame(f.send_s + 120, f.receive_s + 120, "dropped" if i % 2 else "ok", f.latency_ms)
        for i, f in enumerate(stream(1, 10))
    ]
    minutes = st.bin_minutes(first + second + last, flat_rss(3, 400.0, 25.0))
    checks = {c.name: c for c in st.verdict(minutes)}
    assert checks["answered rate"].passed is False
    assert "-50.0%" in checks["answered rate"].detail
    # Medians at 87.5 s and 147.5 s of a 25 MiB/min rise: 25 MiB apart, 26.2 MB.
    assert checks["RSS"].passed is False
    assert "+26.2 MB" in checks["RSS"].detail
    assert checks["errors"].passed is True


def test_rss_tolerance_is_in_megabytes_not_mebibytes():
    # 19.5 MiB = 20.4 MB: over the limit although under 20 MiB.
    minutes = st.bin_minutes(stream(3, 1), flat_rss(3, 400.0, 19.5))
    rss = {c.name: c for c in st.verdict(minutes)}["RSS"]
    assert rss.passed is False and "+20.4 MB" in rss.detail


def test_cpu_is_per_minute_in_percent_of_a_core_and_others_exclude_server_and_client():
    # Server 0.8 s of CPU a second, client 0.1, the machine 1.5 in all: others 0.6.
    samples = [
        st.Sample(T0 + t, 400.0, 0.8 * t, 0.1 * t, 100.0 + 1.5 * t) for t in range(0, 125, 5)
    ]
    minutes = st.bin_minutes(stream(2, 5), samples)
    assert minutes[0].server_cpu == pytest.approx(80.0)
    assert minutes[1].others_cpu == pytest.approx(60.0)
    assert "| 80% | 60% |" in st.table(minutes)
    # Without CPU columns (or the client's), the cells are empty.
    bare = st.bin_minutes(stream(2, 5), [st.Sample(s.t, 400.0, s.server_cpu_s) for s in samples])
    assert bare[0].server_cpu == pytest.approx(80.0) and bare[0].others_cpu is None


def test_samples_are_read_with_or_without_the_cpu_columns(tmp_path):
    path = tmp_path / "rss.tsv"
    path.write_text("100.5\t0.0\t291600\t2.64\n105.5\t5.0\t373264\t3.15\t1.5\t\t20.25\n")
    a, b = st.read_samples(str(path))
    assert a == st.Sample(100.5, 291600 / 1024)
    assert b == st.Sample(105.5, 373264 / 1024, 1.5, None, 20.25)


def test_the_plot_is_one_svg_with_a_panel_more_when_cpu_was_sampled():
    minutes = st.bin_minutes(stream(3, 2), flat_rss(3, 400.0))
    svg = st.svg(minutes)
    assert svg.startswith("<svg") and svg.rstrip().endswith("</svg>")
    assert svg.count("<polyline") == 5  # sent, answered; p50, p99; RSS
    samples = [st.Sample(T0 + t, 400.0, 0.5 * t, 0.1 * t, t) for t in range(0, 185, 5)]
    assert st.svg(st.bin_minutes(stream(3, 2), samples)).count("<polyline") == 7


def test_the_rate_can_be_held_to_minute_2_and_the_rss_to_5_mb():
    # Minute 1 answers 15/s (warm-up), minutes 2 and 3 10/s; RSS grows 6 MiB a minute.
    first = stream(1, 15)
    rest = [
        st.Frame(f.send_s + 60 * k, f.receive_s + 60 * k, "ok", 5.0)
        for k in (1, 2)
        for f in stream(1, 10)
    ]
    minutes = st.bin_minutes(first + rest, flat_rss(3, 400.0, 6.0))
    default = {c.name: c for c in st.verdict(minutes)}
    assert (
        default["answered rate"].passed is False
        and "against minute 1" in default["answered rate"].detail
    )
    assert default["RSS"].passed is True
    issue = {c.name: c for c in st.verdict(minutes, rate_from=2, rss_mb=5.0)}
    assert issue["answered rate"].passed is True
    assert "against minute 2" in issue["answered rate"].detail
    assert issue["RSS"].passed is False and "limit ±5 MB" in issue["RSS"].detail
