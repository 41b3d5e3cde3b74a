"""Plots a soak's samples (scripts/soak.sh --out DIR): resident memory and frames per second
against time, as one SVG with two panels. Standard library only.

    python3 scripts/plot_soak.py soak.tsv soak.svg
"""

import math
import sys

WIDTH, PANEL_H = 920, 300
LEFT, RIGHT, TOP, BOTTOM = 70, 30, 40, 46


def nice_step(span: float, ticks: int = 6) -> float:
    """A 1-2-5 step giving about `ticks` ticks over `span`."""
    raw = max(span, 1e-9) / ticks
    power = 10 ** math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if raw <= m * power:
            return m * power
    return 10 * power


def y_grid(box: tuple[float, float, float, float], y_min: float, y_max: float, sy) -> list[str]:
    """The horizontal grid lines and their labels from `y_min` to `y_max` (`sy`: value to SVG
    y), then the frame of the plot area `box` = (left, top, width, height)."""
    left, top, w, h = box
    out = []
    step = nice_step(y_max - y_min, 5)
    for i in range(int((y_max - y_min) / step) + 1):
        v = y_min + i * step
        out.append(
            f'<line x1="{left}" y1="{sy(v):.1f}" x2="{left + w}" y2="{sy(v):.1f}" stroke="#eee"/>'
        )
        out.append(
            f'<text x="{left - 6}" y="{sy(v) + 4:.1f}" font-size="11" '
            f'text-anchor="end">{v:g}</text>'
        )
    out.append(f'<rect x="{left}" y="{top}" width="{w}" height="{h}" fill="none" stroke="#444"/>')
    return out


def panel(
    y0: float, title: str, xs, ys, y_label: str, colour: str, x_max: float, y_min: float = 0.0
) -> str:
    """One chart at vertical offset `y0`: a line of (xs, ys) with axes, ticks and grid."""
    w, h = WIDTH - LEFT - RIGHT, PANEL_H - TOP - BOTTOM
    y_max = max(ys) * 1.1 if ys and max(ys) > y_min else y_min + 1

    def sx(x: float) -> float:
        return LEFT + w * x / x_max

    def sy(y: float) -> float:
        return y0 + TOP + h * (1 - (y - y_min) / (y_max - y_min))

    out = [f'<text x="{LEFT}" y="{y0 + 24}" font-size="15" font-weight="bold">{title}</text>']
    step = nice_step(x_max / 60) * 60
    for i in range(int(x_max / step) + 1):
        t = i * step
        out.append(
            f'<line x1="{sx(t):.1f}" y1="{y0 + TOP}" x2="{sx(t):.1f}" y2="{y0 + TOP + h}" '
            'stroke="#eee"/>'
        )
        out.append(
            f'<text x="{sx(t):.1f}" y="{y0 + TOP + h + 16}" font-size="11" '
            f'text-anchor="middle">{t / 60:g}</text>'
        )
    out += y_grid((LEFT, y0 + TOP, w, h), y_min, y_max, sy)
    points = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y in zip(xs, ys, strict=True))
    out.append(f'<polyline points="{points}" fill="none" stroke="{colour}" stroke-width="1.6"/>')
    out.append(
        f'<text x="{LEFT + w / 2}" y="{y0 + PANEL_H - 8}" font-size="12" '
        'text-anchor="middle">minutes since ready</text>'
    )
    out.append(
        f'<text x="16" y="{y0 + TOP + h / 2}" font-size="12" text-anchor="middle" '
        f'transform="rotate(-90 16 {y0 + TOP + h / 2})">{y_label}</text>'
    )
    return "\n".join(out)


def main() -> None:
    with open(sys.argv[1]) as f:
        rows = [line.split("\t") for line in f if line.strip()]
    t = [float(r[0]) for r in rows]
    rss = [float(r[1]) for r in rows]
    frames = [float(r[2]) for r in rows]
    rate = [float(r[3]) for r in rows][1:]
    x_max = max(t[-1], 1.0)
    title = (
        f"tre serve soak: {int(frames[-1])} frames in {t[-1] / 60:.1f} min, "
        f"RSS {min(rss[2:] or rss):.0f}–{max(rss[2:] or rss):.0f} MiB after the first 10 s"
    )
    body = [
        panel(0, title, t, rss, "resident memory, MiB", "#1f77b4", x_max),
        panel(
            PANEL_H,
            "frames run per second (5 s windows)",
            t[1:],
            rate,
            "frames/s",
            "#d62728",
            x_max,
        ),
    ]
    svg = (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{2 * PANEL_H}" '
        f'font-family="sans-serif">\n<rect width="100%" height="100%" fill="white"/>\n'
        + "\n".join(body)
        + "\n</svg>\n"
    )
    with open(sys.argv[2], "w") as f:
        f.write(svg)


if __name__ == "__main__":
    main()
