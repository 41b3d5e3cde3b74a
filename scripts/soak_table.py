"""Per-minute table and plot of a stream soak (scripts/soak_stream.sh): from the client's
frames.csv and the server's RSS samples, one row per minute since the first frame was sent, the
verdict on the three criteria of a stream soak, and an SVG. Standard library only.

    python3 scripts/soak_table.py frames.csv rss.tsv --md table.md --svg soak-stream.svg

Frames are binned by their send time (a frame without one, by its receive time). A minute is
whole when frames were still being sent within a second of its end; a shorter last bin is shown
and marked partial, and left out of the verdict. Latencies are the client's (send to answer)
over the answered frames, percentiles by nearest rank, as `tre loadtest` reports them. RSS is the
median of the samples taken in the minute; CPU, in % of one core, runs from the minute's first
sample to its last: the server's, and the rest of the machine's less the client's (other work
on a shared machine). `dropped` is the stream's latest-frame-wins answer to
a frame that a newer one replaced while the worker was busy: not an error. Every other status
but `ok` (`error:CODE`, `lost:REASON`) is an error.

The verdict: the answered rate of the last whole minute within 5% of the first's, the RSS of the
last whole minute within 20 MB (10^6 bytes) of the second minute's, and no error row.
`--rate-from-minute 2 --rss-mb 5` asks the camera-rate soak's rule instead: the rate against
minute 2's (minute 1 holds the warm-up) and the RSS within 5 MB.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
from dataclasses import dataclass, field

from plot_soak import y_grid

RATE_TOLERANCE = 0.05
RSS_TOLERANCE_MB = 20.0
MIB = 1024 * 1024
# A minute counts as whole when frames were still being sent this close to its end, seconds.
WHOLE_SLACK_S = 1.0


@dataclass
class Frame:
    """One row of frames.csv: when it was sent and answered (unix seconds), how, how fast."""

    send_s: float | None
    receive_s: float
    status: str
    latency_ms: float | None = None


@dataclass
class Minute:
    """The frames sent in one minute of the run, and the server's RSS then."""

    index: int
    seconds: float
    sent: int = 0
    answered: int = 0
    dropped: int = 0
    errors: int = 0
    latencies: list[float] = field(default_factory=list)
    rss_mib: float | None = None
    # CPU over the minute, % of one core: the server, and everything else on the machine but
    # the server and the client.
    server_cpu: float | None = None
    others_cpu: float | None = None

    @property
    def whole(self) -> bool:
        return self.seconds >= 60.0

    @property
    def answered_per_s(self) -> float:
        return self.answered / self.seconds if self.seconds > 0 else 0.0

    @property
    def sent_per_s(self) -> float:
        return self.sent / self.seconds if self.seconds > 0 else 0.0


def read_frames(path: str) -> list[Frame]:
    """frames.csv of `tre client`: sequence,name,send_unix_us,receive_unix_us,latency_ms,
    server_latency_ms,dropped,status."""
    frames = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            send = row["send_unix_us"]
            latency = row["latency_ms"]
            frames.append(
                Frame(
                    send_s=int(send) / 1e6 if send else None,
                    receive_s=int(row["receive_unix_us"]) / 1e6,
                    status=row["status"],
                    latency_ms=float(latency) if latency else None,
                )
            )
    return frames


@dataclass
class Sample:
    """One line of rss.tsv: unix seconds, the server's RSS, and CPU seconds used so far by the
    server, the client and the whole machine (None where not recorded)."""

    t: float
    rss_mib: float
    server_cpu_s: float | None = None
    client_cpu_s: float | None = None
    machine_cpu_s: float | None = None


def read_samples(path: str) -> list[Sample]:
    """rss.tsv of scripts/soak_stream.sh: unix time, seconds since ready, VmRSS KiB, load
    average, then (optional) CPU seconds of the server, the client and the machine."""

    def number(cols: list[str], i: int) -> float | None:
        return float(cols[i]) if len(cols) > i and cols[i].strip() else None

    samples = []
    with open(path) as f:
        for line in f:
            cols = line.rstrip("\n").split("\t")
            if len(cols) >= 3 and cols[2].strip():
                samples.append(
                    Sample(
                        float(cols[0]),
                        int(cols[2]) / 1024,
                        number(cols, 4),
                        number(cols, 5),
                        number(cols, 6),
                    )
                )
    return samples


def cpu_percent(inside: list[Sample], attr: str) -> float | None:
    """CPU used between the first and last sample of `inside` that have `attr`, in % of one
    core."""
    have = [s for s in inside if getattr(s, attr) is not None]
    if len(have) < 2 or have[-1].t <= have[0].t:
        return None
    return 100 * (getattr(have[-1], attr) - getattr(have[0], attr)) / (have[-1].t - have[0].t)


def percentile(values: list[float], q: float) -> float:
    """The nearest-rank percentile `q` (0..100) of `values` (not empty)."""
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100 * len(ordered)))
    return ordered[rank - 1]


def is_error(status: str) -> bool:
    return status not in ("ok", "dropped")


def bin_minutes(frames: list[Frame], samples: list[Sample]) -> list[Minute]:
    """One Minute per minute since the first send, the last one possibly partial."""
    sends = [f.send_s for f in frames if f.send_s is not None]
    if not sends:
        return []
    t0, t_last = min(sends), max(sends)
    count = int((t_last - t0) // 60) + 1
    minutes = []
    for k in range(count):
        span = t_last - t0 - 60 * k
        minutes.append(Minute(k + 1, 60.0 if span + WHOLE_SLACK_S >= 60 else span))
    for f in frames:
        t = f.send_s if f.send_s is not None else f.receive_s
        m = minutes[min(max(int((t - t0) // 60), 0), count - 1)]
        m.sent += 1
        if f.status == "ok":
            m.answered += 1
            if f.latency_ms is not None:
                m.latencies.append(f.latency_ms)
        elif f.status == "dropped":
            m.dropped += 1
        else:
            m.errors += 1
    for m in minutes:
        start = t0 + 60 * (m.index - 1)
        inside = [s for s in samples if start <= s.t < start + 60]
        m.rss_mib = statistics.median(s.rss_mib for s in inside) if inside else None
        m.server_cpu = cpu_percent(inside, "server_cpu_s")
        machine = cpu_percent(inside, "machine_cpu_s")
        client = cpu_percent(inside, "client_cpu_s")
        if machine is not None and m.server_cpu is not None and client is not None:
            m.others_cpu = machine - m.server_cpu - client
    return minutes


@dataclass
class Check:
    """One criterion of the verdict."""

    name: str
    passed: bool | None  # None: not enough data to tell
    detail: str


def verdict(
    minutes: list[Minute], rate_from: int = 1, rss_mb: float = RSS_TOLERANCE_MB
) -> list[Check]:
    """The three criteria, on the whole minutes (errors on every row): the answered rate of
    the last whole minute against whole minute `rate_from` (1: the first), the RSS against the
    second's within `rss_mb` MB."""
    whole = [m for m in minutes if m.whole]
    checks = []
    if len(whole) > rate_from:
        first, last = whole[rate_from - 1], whole[-1]
        change = (last.answered_per_s - first.answered_per_s) / first.answered_per_s
        checks.append(
            Check(
                "answered rate",
                abs(change) <= RATE_TOLERANCE,
                f"minute {last.index} {last.answered_per_s:.2f}/s against minute {first.index} "
                f"{first.answered_per_s:.2f}/s: {change * 100:+.1f}% "
                f"(limit ±{RATE_TOLERANCE * 100:g}%)",
            )
        )
    else:
        checks.append(Check("answered rate", None, f"not more than {rate_from} whole minutes"))
    second = whole[1] if len(whole) >= 2 else None
    if second is not None and second.rss_mib is not None and whole[-1].rss_mib is not None:
        last = whole[-1]
        diff_mb = (last.rss_mib - second.rss_mib) * MIB / 1e6
        checks.append(
            Check(
                "RSS",
                abs(diff_mb) <= rss_mb,
                f"minute {last.index} {last.rss_mib:.1f} MiB against minute 2 "
                f"{second.rss_mib:.1f} MiB: {diff_mb:+.1f} MB (limit ±{rss_mb:g} MB)",
            )
        )
    else:
        checks.append(Check("RSS", None, "no RSS samples in minute 2 or in the last minute"))
    errors = sum(m.errors for m in minutes)
    checks.append(Check("errors", errors == 0, f"{errors} error rows of {sum_sent(minutes)}"))
    return checks


def sum_sent(minutes: list[Minute]) -> int:
    return sum(m.sent for m in minutes)


def fmt_ms(values: list[float], q: float | None) -> str:
    if not values:
        return "–"
    return f"{(max(values) if q is None else percentile(values, q)):.1f}"


def table(minutes: list[Minute]) -> str:
    """The per-minute table, markdown."""
    lines = [
        "| minute | sent | sent/s | answered | answered/s | dropped | errors "
        "| p50 ms | p90 ms | p99 ms | max ms | RSS MiB | server CPU | other CPU |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for m in minutes:
        label = str(m.index) if m.whole else f"{m.index} (partial, {m.seconds:.1f} s)"
        rss = "–" if m.rss_mib is None else f"{m.rss_mib:.1f}"
        cpu = ["–" if c is None else f"{c:.0f}%" for c in (m.server_cpu, m.others_cpu)]
        lines.append(
            f"| {label} | {m.sent} | {m.sent_per_s:.2f} | {m.answered} | {m.answered_per_s:.2f} "
            f"| {m.dropped} "
            f"| {m.errors} | {fmt_ms(m.latencies, 50)} | {fmt_ms(m.latencies, 90)} "
            f"| {fmt_ms(m.latencies, 99)} | {fmt_ms(m.latencies, None)} | {rss} "
            f"| {cpu[0]} | {cpu[1]} |"
        )
    return "\n".join(lines)


def report(minutes: list[Minute], checks: list[Check]) -> str:
    """The table, the totals and the verdict, markdown."""
    every = [x for m in minutes for x in m.latencies]
    sent = sum_sent(minutes)
    answered = sum(m.answered for m in minutes)
    dropped = sum(m.dropped for m in minutes)
    errors = sum(m.errors for m in minutes)
    whole = sum(1 for m in minutes if m.whole)
    total = (
        f"All: {sent} frames sent, {answered} answered, {dropped} dropped, {errors} errors; "
        f"latency p50 {fmt_ms(every, 50)}, p90 {fmt_ms(every, 90)}, p99 {fmt_ms(every, 99)}, "
        f"max {fmt_ms(every, None)} ms; {whole} whole minute{'' if whole == 1 else 's'}."
    )
    word = {True: "pass", False: "FAIL", None: "n/a"}
    if any(c.passed is False for c in checks):
        overall = "FAIL"
    elif all(c.passed for c in checks):
        overall = "PASS"
    else:
        overall = "INCOMPLETE (a criterion could not be told)"
    lines = [table(minutes), "", total, "", f"Verdict: {overall}", ""]
    lines += [f"- {c.name}: {word[c.passed]}: {c.detail}" for c in checks]
    return "\n".join(lines) + "\n"


WIDTH, PANEL_H = 920, 260
LEFT, RIGHT, TOP, BOTTOM = 70, 150, 40, 46


def panel(y0: float, title: str, x_max: int, series, y_label: str) -> str:
    """One chart at vertical offset `y0`: `series` = [(name, colour, xs, ys)], lines with dots,
    x in minutes (1..x_max), y from 0."""
    w, h = WIDTH - LEFT - RIGHT, PANEL_H - TOP - BOTTOM
    top = max((y for _, _, _, ys in series for y in ys), default=1.0)
    y_max = top * 1.15 if top > 0 else 1.0

    def sx(x: float) -> float:
        return LEFT + w * (x - 0.5) / x_max

    def sy(y: float) -> float:
        return y0 + TOP + h * (1 - y / y_max)

    out = [f'<text x="{LEFT}" y="{y0 + 24}" font-size="15" font-weight="bold">{title}</text>']
    for i in range(1, x_max + 1):
        out.append(
            f'<text x="{sx(i):.1f}" y="{y0 + TOP + h + 16}" font-size="11" '
            f'text-anchor="middle">{i}</text>'
        )
    out += y_grid((LEFT, y0 + TOP, w, h), 0.0, y_max, sy)
    for n, (name, colour, xs, ys) in enumerate(series):
        points = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y in zip(xs, ys, strict=True))
        out.append(
            f'<polyline points="{points}" fill="none" stroke="{colour}" stroke-width="1.6"/>'
        )
        out += [
            f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="3" fill="{colour}"/>'
            for x, y in zip(xs, ys, strict=True)
        ]
        ly = y0 + TOP + 12 + 18 * n
        out.append(
            f'<line x1="{LEFT + w + 12}" y1="{ly - 4}" x2="{LEFT + w + 32}" y2="{ly - 4}" '
            f'stroke="{colour}" stroke-width="2"/>'
        )
        out.append(f'<text x="{LEFT + w + 38}" y="{ly}" font-size="12">{name}</text>')
    out.append(
        f'<text x="{LEFT + w / 2}" y="{y0 + PANEL_H - 8}" font-size="12" '
        'text-anchor="middle">minute since the first frame</text>'
    )
    out.append(
        f'<text x="16" y="{y0 + TOP + h / 2}" font-size="12" text-anchor="middle" '
        f'transform="rotate(-90 16 {y0 + TOP + h / 2})">{y_label}</text>'
    )
    return "\n".join(out)


def svg(minutes: list[Minute]) -> str:
    """Panels over the whole minutes: answered and sent per second, latency p50 and p99, median
    RSS, and the CPU of the server and of other work where it was sampled."""
    whole = [m for m in minutes if m.whole]
    xs = [m.index for m in whole]
    timed = [m for m in whole if m.latencies]
    sized = [m for m in whole if m.rss_mib is not None]
    x_max = max(xs, default=1)
    sent = sum(m.sent for m in whole)
    answered = sum(m.answered for m in whole)
    panels = [
        (
            f"one stream, {len(whole)} min: {answered} of {sent} frames answered",
            [
                ("sent/s", "#999999", xs, [m.sent_per_s for m in whole]),
                ("answered/s", "#2ca02c", xs, [m.answered_per_s for m in whole]),
            ],
            "frames/s",
        ),
        (
            "latency, send to answer",
            [
                (
                    "p50",
                    "#ff7f0e",
                    [m.index for m in timed],
                    [percentile(m.latencies, 50) for m in timed],
                ),
                (
                    "p99",
                    "#d62728",
                    [m.index for m in timed],
                    [percentile(m.latencies, 99) for m in timed],
                ),
            ],
            "ms",
        ),
        (
            "server resident memory (median of the minute's 5 s samples)",
            [("RSS", "#1f77b4", [m.index for m in sized], [m.rss_mib for m in sized])],
            "MiB",
        ),
    ]
    cpu = [m for m in whole if m.server_cpu is not None and m.others_cpu is not None]
    if cpu:
        panels.append(
            (
                "CPU, % of one core: the server, and other work on the machine",
                [
                    ("server", "#9467bd", [m.index for m in cpu], [m.server_cpu for m in cpu]),
                    ("others", "#8c564b", [m.index for m in cpu], [m.others_cpu for m in cpu]),
                ],
                "% of a core",
            )
        )
    body = [
        panel(i * PANEL_H, title, x_max, series, label)
        for i, (title, series, label) in enumerate(panels)
    ]
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" '
        f'height="{len(panels) * PANEL_H}" font-family="sans-serif">\n'
        '<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(body) + "\n</svg>\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("frames_csv")
    parser.add_argument("rss_tsv")
    parser.add_argument("--md", help="write the table and verdict here (default: stdout only)")
    parser.add_argument("--svg", help="write the plot here")
    parser.add_argument(
        "--rate-from-minute",
        type=int,
        default=1,
        help="the whole minute the last one's answered rate is held to (default 1)",
    )
    parser.add_argument(
        "--rss-mb",
        type=float,
        default=RSS_TOLERANCE_MB,
        help=f"the RSS limit, MB (default {RSS_TOLERANCE_MB:g})",
    )
    args = parser.parse_args()
    if args.rate_from_minute < 1:
        parser.error("--rate-from-minute counts from 1")
    minutes = bin_minutes(read_frames(args.frames_csv), read_samples(args.rss_tsv))
    text = report(minutes, verdict(minutes, args.rate_from_minute, args.rss_mb))
    if args.md:
        with open(args.md, "w") as f:
            f.write(text)
    else:
        print(text, end="")
    if args.svg:
        with open(args.svg, "w") as f:
            f.write(svg(minutes))


if __name__ == "__main__":
    main()
