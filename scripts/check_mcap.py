"""Read a recording of `tre ros2 --record`, `tre map --record` or `tre client --record` with
the Python `mcap` and `mcap-ros2-support` packages (an independent reader) and check it: every
channel's schema and encodings (ROS 2 CDR only, unless --foxglove: then the Foxglove JSON
channels too), `offered_qos_profiles` on every channel (transient-local for the occupancy
grid), compressed chunks, every message of every channel decoded, the message counts, and the
values (the roughness against a `tre infer` .npy, the map against `tre map`'s layers, the
Foxglove channels against the ROS 2 ones). With --render, draw what a `tre ros2` recording
holds as a PNG (docs/ros2.md's picture).

    python scripts/check_mcap.py run.mcap --frames 5 [--kind ros2|map|client] [--foxglove]
        [--roughness-npy f.npy] [--map-dir DIR] [--render out.png]
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import sys
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

# topic: (schema name, schema encoding, message encoding, count rule)
OUTPUTS = {
    "/tre/roughness": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/tre/uncertainty": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/tre/traversal": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/tre/roughness/compressed": ("sensor_msgs/msg/CompressedImage", "ros2msg", "cdr"),
    "/tre/uncertainty/compressed": ("sensor_msgs/msg/CompressedImage", "ros2msg", "cdr"),
    "/tre/traversal/compressed": ("sensor_msgs/msg/CompressedImage", "ros2msg", "cdr"),
    "/tre/grid_map": ("grid_map_msgs/msg/GridMap", "ros2msg", "cdr"),
    "/tre/occupancy": ("nav_msgs/msg/OccupancyGrid", "ros2msg", "cdr"),
    "/tre/roughness/foxglove": ("foxglove.RawImage", "jsonschema", "json"),
    "/tre/grid/foxglove": ("foxglove.Grid", "jsonschema", "json"),
}
INPUTS = {
    "/camera/depth/image_rect_raw": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/camera/depth/camera_info": ("sensor_msgs/msg/CameraInfo", "ros2msg", "cdr"),
    "/odom": ("nav_msgs/msg/Odometry", "ros2msg", "cdr"),
}
# `tre map --record`: per frame its depth, intrinsics, pose and roughness; the map once.
MAP_FRAMES = {
    "/camera/depth/image_rect_raw": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/camera/depth/camera_info": ("sensor_msgs/msg/CameraInfo", "ros2msg", "cdr"),
    "/tre/camera_pose": ("geometry_msgs/msg/PoseStamped", "ros2msg", "cdr"),
    "/tre/roughness": OUTPUTS["/tre/roughness"],
    "/tre/roughness/foxglove": OUTPUTS["/tre/roughness/foxglove"],
}
MAP_ONCE = {t: OUTPUTS[t] for t in ("/tre/grid_map", "/tre/grid/foxglove", "/tre/occupancy")}
# `tre client --record`: per frame the colour as sent (when one was), the depth in metres and
# the answer.
CLIENT_COLOUR = {
    "/camera/color/image_raw/compressed": ("sensor_msgs/msg/CompressedImage", "ros2msg", "cdr"),
}
CLIENT_FRAMES = {
    "/camera/depth/image_rect_raw": ("sensor_msgs/msg/Image", "ros2msg", "cdr"),
    "/tre/roughness": OUTPUTS["/tre/roughness"],
    "/tre/roughness/foxglove": OUTPUTS["/tre/roughness/foxglove"],
}


def fail(msg: str) -> None:
    print(f"check_mcap: {msg}", file=sys.stderr)
    sys.exit(1)


def check_channel_metadata(summary) -> None:
    """Every channel offers its QoS as rosbag2 reads it; the occupancy grid is transient-local.
    Every chunk is compressed (zstd or lz4)."""
    for ch in summary.channels.values():
        qos = ch.metadata.get("offered_qos_profiles")
        if not qos or "reliability:" not in qos or "durability:" not in qos:
            fail(f"{ch.topic}: no offered_qos_profiles ({ch.metadata})")
        durability = qos.split("durability:")[1].split()[0]
        want = "1" if ch.topic.endswith("/occupancy") else "2"
        if durability != want:
            fail(f"{ch.topic}: durability {durability}, expected {want}: {qos}")
    kinds = {c.compression for c in summary.chunk_indexes}
    if not kinds or not kinds <= {"zstd", "lz4"}:
        fail(f"chunk compression {kinds}, expected zstd or lz4")


def read(path: Path) -> tuple[dict, dict[str, list]]:
    """Channels by topic (schema name and encodings), and the messages of each topic, decoded
    (every message of every channel)."""
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        if summary is None:
            fail("no summary: the recording was not finished")
        check_channel_metadata(summary)
        channels = {}
        for ch in summary.channels.values():
            schema = summary.schemas[ch.schema_id]
            channels[ch.topic] = (schema.name, schema.encoding, ch.message_encoding)
        cdr_topics = [t for t, c in channels.items() if c[2] == "cdr"]
        messages: dict[str, list] = {t: [] for t in channels}
        for _, channel, _, decoded in reader.iter_decoded_messages(topics=cdr_topics):
            messages[channel.topic].append(decoded)
        f.seek(0)
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages():
            if channel.message_encoding == "json":
                messages[channel.topic].append(json.loads(message.data))
        total = sum(s.message_count for s in [summary.statistics] if s is not None)
        if total != sum(len(m) for m in messages.values()):
            fail(f"{total} messages in the statistics, {sum(map(len, messages.values()))} decoded")
    return channels, messages


def float_image(msg) -> np.ndarray:
    if msg.encoding != "32FC1" or msg.is_bigendian:
        fail(f"roughness encoding {msg.encoding}, big-endian {msg.is_bigendian}")
    return np.frombuffer(bytes(msg.data), "<f4").reshape(msg.height, msg.width)


def grid_layer(msg, name: str) -> np.ndarray:
    """A GridMap layer in tre map's layout (row 0 at the largest y, column 0 at the smallest x)."""
    arr = msg.data[list(msg.layers).index(name)]
    dims = [(d.label, d.size, d.stride) for d in arr.layout.dim]
    if [d[0] for d in dims] != ["column_index", "row_index"]:
        fail(f"grid_map dimension labels {dims}")
    cols, rows = dims[0][1], dims[1][1]
    # Column-major: data[c * rows + r], r along -x, c along -y.
    a = np.asarray(arr.data, dtype=np.float32).reshape(cols, rows)
    return a[:, ::-1]


def foxglove_layer(msg: dict, name: str) -> np.ndarray:
    field = next(f for f in msg["fields"] if f["name"] == name)
    data = np.frombuffer(base64.b64decode(msg["data"]), np.uint8)
    side = msg["column_count"]
    stride = msg["cell_stride"]
    cells = data.reshape(-1, stride)[:, field["offset"] : field["offset"] + 4]
    values = cells.copy().view("<f4").reshape(-1, side)
    return values[::-1, :]  # rows from the bottom (+y) to tre map's top-down rows


def same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))


def expect(channels: dict, messages: dict, topics: dict, count: int, at_least: bool) -> None:
    """Each topic's channel as `topics` says, with `count` messages (or at least `count`)."""
    for topic, want in topics.items():
        if channels.get(topic) != want:
            fail(f"{topic}: channel {channels.get(topic)}, expected {want}")
        n = len(messages[topic])
        if n < count or (n > count and not at_least):
            fail(f"{topic}: {n} messages, expected {'at least ' if at_least else ''}{count}")


FOXGLOVE = ("/tre/roughness/foxglove", "/tre/grid/foxglove")


def without_foxglove(topics: dict) -> dict:
    return {t: c for t, c in topics.items() if t not in FOXGLOVE}


def check(
    path: Path, frames: int, kind: str, roughness_npy: Path | None, foxglove: bool
) -> dict[str, list]:
    channels, messages = read(path)
    global OUTPUTS, MAP_FRAMES, MAP_ONCE, CLIENT_FRAMES
    if not foxglove:
        others = [t for t, c in channels.items() if c[1:] != ("ros2msg", "cdr")]
        if others:
            fail(f"channels other than ROS 2 CDR: {others}")
        OUTPUTS, MAP_FRAMES, MAP_ONCE, CLIENT_FRAMES = map(
            without_foxglove, (OUTPUTS, MAP_FRAMES, MAP_ONCE, CLIENT_FRAMES)
        )
    if kind == "ros2":
        expect(channels, messages, OUTPUTS, frames, at_least=False)
        expect(channels, messages, INPUTS, frames, at_least=True)
    elif kind == "map":
        expect(channels, messages, MAP_FRAMES, frames, at_least=False)
        expect(channels, messages, MAP_ONCE, 1, at_least=False)
    else:
        expect(channels, messages, CLIENT_FRAMES, frames, at_least=False)
        if any(t in channels for t in CLIENT_COLOUR):
            expect(channels, messages, CLIENT_COLOUR, frames, at_least=False)
    rough = float_image(messages["/tre/roughness"][-1])
    if foxglove:
        fox = messages["/tre/roughness/foxglove"][-1]
        fox_img = np.frombuffer(base64.b64decode(fox["data"]), "<f4").reshape(
            fox["height"], fox["width"]
        )
        if not same(rough, fox_img):
            fail("the foxglove.RawImage roughness differs from the sensor_msgs/Image one")
    if roughness_npy is not None:
        want = np.load(roughness_npy).astype(np.float32)
        if not same(rough, want):
            fail(f"the recorded roughness differs from {roughness_npy}")
    if kind == "ros2":
        check_png(messages["/tre/roughness/compressed"][-1], rough)
    if kind != "client":
        check_grid(messages, foxglove)
    counts = {t: len(m) for t, m in sorted(messages.items())}
    print(
        json.dumps(
            {"channels": {t: list(c) for t, c in sorted(channels.items())}, "messages": counts},
            indent=1,
        )
    )
    return messages


def check_png(msg, rough: np.ndarray) -> None:
    """The roughness's PNG (image_transport's compressed): millimetres to the nearest, 0 for
    no data, of the same frame's 32FC1 roughness."""
    from PIL import Image

    if msg.format != "mono16; png compressed mono16":
        fail(f"roughness PNG format {msg.format!r}")
    png = np.asarray(Image.open(io.BytesIO(bytes(msg.data))), dtype=np.int64)
    # As the node rounds: in float64, half away from zero (the roughness is not negative).
    r = np.nan_to_num(rough.astype(np.float64) * 1000.0, nan=0.0)
    mm = np.where(np.isfinite(rough), np.clip(np.floor(r + 0.5), 1, 65535), 0)
    if png.shape != rough.shape or np.any(png != mm.astype(np.int64)):
        fail("the roughness PNG is not the roughness in millimetres")


def check_grid(messages: dict[str, list], foxglove: bool) -> None:
    """The last map: foxglove.Grid (if recorded) equal to the GridMap, the occupancy its
    traversal layer."""
    grid = messages["/tre/grid_map"][-1]
    for name in grid.layers if foxglove else []:
        fgrid = messages["/tre/grid/foxglove"][-1]
        if not same(grid_layer(grid, name), foxglove_layer(fgrid, name)):
            fail(f"layer {name}: foxglove.Grid and grid_map_msgs/GridMap differ")
    occ = np.asarray(messages["/tre/occupancy"][-1].data, dtype=np.int8)
    if not set(np.unique(occ)) <= {-1, 0, 100}:
        fail(f"occupancy values {np.unique(occ)}")
    trav = grid_layer(grid, "traversal")[::-1, :].ravel()
    want_occ = np.where(trav == 1, 0, np.where(trav == 2, 100, -1))
    if not np.array_equal(occ, want_occ):
        fail("occupancy differs from the grid map's traversal layer")


def check_map_dir(messages: dict[str, list], map_dir: Path) -> None:
    """The recorded map's layers equal to `tre map`'s `<layer>.npy` files."""
    grid = messages["/tre/grid_map"][-1]
    for name in grid.layers:
        want = np.load(map_dir / f"{name}.npy").astype(np.float32)
        if not same(grid_layer(grid, name), want):
            fail(f"layer {name}: the recorded map differs from {map_dir / name}.npy")


def render(messages: dict[str, list], out: Path) -> None:
    """Depth in, roughness and three-state out, the map's elevation and occupancy, side by side."""
    from PIL import Image, ImageDraw

    def colour(a: np.ndarray, lo: float, hi: float) -> Image.Image:
        t = np.clip((a - lo) / (hi - lo), 0, 1)
        rgb = np.stack([t * 255, (1 - np.abs(2 * t - 1)) * 200, (1 - t) * 255], -1)
        rgb[~np.isfinite(a)] = 40
        return Image.fromarray(rgb.astype(np.uint8))

    d = messages["/camera/depth/image_rect_raw"][-1]
    depth = np.frombuffer(bytes(d.data), "<u2").reshape(d.height, d.width) / 1000.0
    depth = np.where(depth > 0, depth, np.nan)
    rough = float_image(messages["/tre/roughness"][-1])
    t = messages["/tre/traversal"][-1]
    trav = np.frombuffer(bytes(t.data), np.uint8).reshape(t.height, t.width)
    pal = np.array([[90, 90, 90], [40, 170, 60], [210, 40, 40]], np.uint8)
    grid = messages["/tre/grid_map"][-1]
    elev = grid_layer(grid, "elevation")
    occ = np.asarray(messages["/tre/occupancy"][-1].data, np.int16).reshape(
        grid_layer(grid, "count").shape
    )[::-1, :]
    occ_rgb = np.where(
        occ[..., None] == 100,
        [210, 40, 40],
        np.where(occ[..., None] == 0, [240, 240, 240], [90, 90, 90]),
    )
    panels = [
        ("depth in (/camera/depth/image_rect_raw)", colour(depth, 0.5, 3.5)),
        ("roughness 0-5 cm (/tre/roughness)", colour(rough, 0.0, 0.05)),
        ("three-state (/tre/traversal)", Image.fromarray(pal[np.minimum(trav, 2)])),
        (
            "map elevation (/tre/grid_map)",
            colour(elev, np.nanmin(elev), np.nanmax(elev)).resize((480, 480), Image.NEAREST),
        ),
        (
            "occupancy (/tre/occupancy)",
            Image.fromarray(occ_rgb.astype(np.uint8)).resize((480, 480), Image.NEAREST),
        ),
    ]
    w = sum(p.width for _, p in panels) + 10 * (len(panels) + 1)
    sheet = Image.new("RGB", (w, 520), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    x = 10
    for title, p in panels:
        sheet.paste(p, (x, 30))
        draw.text((x, 8), title, fill=(0, 0, 0))
        x += p.width + 10
    sheet.save(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mcap", type=Path)
    ap.add_argument("--frames", type=int, required=True, help="frames the node published")
    ap.add_argument("--kind", choices=["ros2", "map", "client"], default="ros2")
    ap.add_argument("--roughness-npy", type=Path, help="tre infer's roughness of the last frame")
    ap.add_argument("--map-dir", type=Path, help="tre map's output folder (the map's layers)")
    ap.add_argument("--render", type=Path, help="write a picture of the recording")
    ap.add_argument(
        "--foxglove", action="store_true", help="the Foxglove JSON channels were asked for"
    )
    args = ap.parse_args()
    messages = check(args.mcap, args.frames, args.kind, args.roughness_npy, args.foxglove)
    if args.map_dir is not None:
        check_map_dir(messages, args.map_dir)
    if args.render:
        render(messages, args.render)


if __name__ == "__main__":
    main()
