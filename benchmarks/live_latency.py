"""Live latency of ``ftrac-design serve``: frame in → TRANSFORM out, over OpenIGTLink on localhost.

A pyigtl client sends rendered 1024² raw frames of a design — a C-arm swing
(:func:`ftrac_design.xray.sweep.render_sweep`, anatomy behind), sent forward then backward so the
motion stays continuous — to a ``serve`` subprocess at 15 and 30 frames/s and times each answer on its own
clock (send → TRANSFORM received: the network, the server's queue and the tracking); frames
the server dropped (its queue full) are counted. Then the sustained rate without drops: frames
sent one at a time, the next as soon as the answer arrives (closed loop). Baseline in the same
run: ``track_image`` on the same frames in this process (the tracking alone), so the ratio of
the live p50 to it is what the link and the server add. The first answers (warm-up) are left out.
The target is p99 ≤ 50 ms for ftrac_2005; the server's default tracker follows the run from frame
to frame (``--independent``: every frame alone, passed through to the server).

**Independent frames** (``--frames independent``): frames that do not follow each other — the
C-arm moved between shots, a new patient — rendered at unrelated workspace poses, sent one every
``--gap`` seconds (so none waits for another), to the server with its default (run) tracker and
with ``--independent``. Each needs the full identification; the bound is ``track`` on one image:
``track_image`` on the same frames in this process. The run tracker first tries the frame from
the previous pose, which fails on an unrelated frame: that attempt is the difference between the
two servers. The server's own part (IMAGE received → answer queued: CRC, decoding, tracking,
composing) is reported beside the tracking alone.

    .venv/bin/python benchmarks/live_latency.py                     # ftrac_2005, 1024², both kinds
    .venv/bin/python benchmarks/live_latency.py --design ftrac_mini --seconds 5 --frames smooth
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _common import machine  # noqa: E402
from igt_support import Server, image_message, recording_client, wait_for  # noqa: E402

from ftrac_design.segment.pipeline import track_image  # noqa: E402


def sweep_frames(out: Path, design: str, n: int, size: int):
    """``n`` frames of a C-arm swing (1024² by default) as :func:`igt_support.rendered_frames` returns
    frames: pixels (n, H, W) uint16, camera, features and camera files."""
    import json

    from igt_support import Frames

    from ftrac_design.design import load_design
    from ftrac_design.design.presets import PRESETS_DIR
    from ftrac_design.features import compute_features, write_features
    from ftrac_design.pose import Camera
    from ftrac_design.pose.simulate import Workspace
    from ftrac_design.xray import ImagingModel
    from ftrac_design.xray.sweep import render_sweep

    cam = Camera(1000.0, (0.44, 0.44), ((size - 1) / 2, (size - 1) / 2))
    features = compute_features(load_design(PRESETS_DIR / f"{design}.toml"))
    R0, t0 = Workspace(cone_deg=10.0, lateral_mm=5.0).sample(
        1, features.nominal_beam_direction, np.random.default_rng(5)
    )
    run = render_sweep(features, R0[0], t0[0], n, cam, ImagingModel(image_shape=(size, size)), seed=5)
    out.mkdir(parents=True, exist_ok=True)
    fpath = write_features(out / f"{design}.features.json", features)
    cpath = out / "camera.json"
    cpath.write_text(json.dumps(cam.to_dict()))
    return Frames(np.asarray(run.raw, np.uint16), cam, Path(fpath), cpath)


def _answers(client) -> dict[float, float]:
    """IMAGE timestamp → arrival time (perf_counter) of its TRANSFORM."""
    log, times = client.incoming_messages.log, client.incoming_messages.times
    return {m.timestamp: t for m, t in zip(log, times) if m.message_type == "TRANSFORM"}


def _server_latency(client, first: float, last: float) -> np.ndarray:
    """The server's own latency (IMAGE received → TRANSFORM queued, ms) of the answers to frames
    stamped ``first`` … ``last``."""
    return np.array(
        [
            float(m.metadata["latency_ms"])
            for m in client.incoming_messages.log
            if m.message_type == "TRANSFORM" and first <= m.timestamp <= last
        ]
    )


def open_loop(client, frames, camera, rate: float, n: int, first_stamp: float) -> tuple[np.ndarray, int]:
    """Send ``n`` frames at ``rate``; (latencies ms of the answered ones, frames dropped)."""
    sent: dict[float, float] = {}
    t0 = time.perf_counter()
    for k in range(n):
        wait = t0 + k / rate - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        stamp = first_stamp + k
        sent[stamp] = time.perf_counter()
        client.send_message(image_message(frames[k % len(frames)], camera, stamp), wait=False)
    last = first_stamp + n - 1
    wait_for(lambda: last in _answers(client), 120)
    got = _answers(client)
    lat = np.array([1e3 * (got[s] - sent[s]) for s in sent if s in got])
    return lat, n - len(lat)


def closed_loop(client, frames, camera, n: int, first_stamp: float) -> float:
    """Frames per second when each frame is sent as soon as the previous answer arrived."""
    t0 = time.perf_counter()
    for k in range(n):
        stamp = first_stamp + k
        client.send_message(image_message(frames[k % len(frames)], camera, stamp), wait=False)
        wait_for(lambda s=stamp: s in _answers(client), 60)
    return n / (time.perf_counter() - t0)


def transport_ms(frame: np.ndarray, cam, rounds: int = 10) -> tuple[float, float]:
    """Median ms to pack one frame as an IMAGE (the sender's side) and to check and decode it
    (CRC, unpack, float32 pixels: the server's side), in this process."""
    from pyigtl import ImageMessage, MessageBase
    from pyigtl.messages import CRC64

    from ftrac_design.igt.link import image_pixels

    pack, decode = [], []
    for _ in range(rounds):
        t = time.perf_counter()
        data = image_message(frame, cam, 1.0).pack()
        t1 = time.perf_counter()
        CRC64(data[58:])
        msg = ImageMessage()
        msg.unpack(MessageBase.parse_header(data[:58]), data[58:])
        image_pixels(msg)
        t2 = time.perf_counter()
        pack.append(1e3 * (t1 - t))
        decode.append(1e3 * (t2 - t1))
    return float(np.median(pack)), float(np.median(decode))


def baseline_ms(fr, detector: str = "auto") -> np.ndarray:
    """``track_image`` alone on each frame, in this process (ms; one warm-up call first)."""
    from ftrac_design.features import load_features
    from ftrac_design.segment import TrackOptions

    features = load_features(fr.features_path)
    opts = TrackOptions(detector=detector)
    track_image(fr.pixels[0], features, fr.camera, opts)
    base = []
    for img in fr.pixels:
        t = time.perf_counter()
        track_image(img, features, fr.camera, opts)
        base.append(1e3 * (time.perf_counter() - t))
    return np.array(base)


def _stats(ms: np.ndarray) -> str:
    p50, p99 = np.percentile(ms, [50, 99])
    return f"p50 {p50:.1f} ms, p99 {p99:.1f} ms, max {ms.max():.1f} ms"


def smooth_run(a: argparse.Namespace) -> None:
    """The swing, forward then backward, at 15 and 30 frames/s, then closed loop."""
    fr = sweep_frames(Path("outputs/bench_live"), a.design, a.distinct, a.size)
    cam = fr.camera
    print(
        f"smooth run: {a.design}, a {a.distinct}-frame {a.size}² swing, sent forward then backward; tracker: "
        f"{'every frame alone' if a.independent else 'run (from the previous pose)'}; detector {a.detector}"
    )
    base = baseline_ms(fr, a.detector)
    print(f"baseline track_image in-process: median {np.median(base):.1f} ms, max {base.max():.1f} ms per frame")
    pk, dc = transport_ms(fr.pixels[0], cam)
    print(
        f"the link per frame ({fr.pixels[0].nbytes / 1e6:.1f} MB): pack {pk:.1f} ms (sender), "
        f"CRC + decode {dc:.1f} ms (server, only for the frames it tracks)"
    )
    # forward then backward: frame k of the stream is a neighbour of frame k − 1
    order = list(range(len(fr.pixels))) + list(range(len(fr.pixels) - 2, 0, -1))
    stream = fr.pixels[order]
    extra = ["--detector", a.detector] + (["--independent"] if a.independent else [])
    server = Server(["--features", str(fr.features_path), "--camera", str(fr.camera_path), *extra])
    try:
        client = recording_client(server.port)
        closed_loop(client, stream, cam, a.warmup, 0.0)
        stamp = 10_000.0
        for rate in (15.0, 30.0):
            n = int(rate * a.seconds)
            lat, dropped = open_loop(client, stream, cam, rate, n, stamp)
            own = _server_latency(client, stamp, stamp + n)
            stamp += 10_000.0
            p99 = np.percentile(lat, 99)
            print(
                f"{rate:.0f} frames/s: {n} sent, {len(lat)} answered, {dropped} dropped; latency {_stats(lat)}; "
                f"p50 / baseline track {np.median(lat) / np.median(base):.2f}; target p99 ≤ 50 ms: "
                f"{'met' if p99 <= 50 else 'MISSED'}; in the server alone (received → sent) {_stats(own)}"
            )
            time.sleep(1.0)
        rate = closed_loop(client, stream, cam, max(2 * a.distinct, 20), stamp)
        print(
            f"sustained rate without drops (closed loop): {rate:.1f} frames/s "
            f"(baseline 1 / median track: {1e3 / np.median(base):.1f} frames/s)"
        )
        client.stop()
    finally:
        rc, text, err = server.interrupt()
    print(text.strip().splitlines()[-1])


def track_command_ms(fr, detector: str = "auto") -> np.ndarray:
    """``track`` on one image, in this process: the command's own path (its default settings,
    ``track_pixels``) on each frame alone, as ``serve --independent`` calls it (ms; one warm-up)."""
    from ftrac_design.workflows.serve import frame_by_frame_tracker
    from ftrac_design.workflows.track_run import TrackSetup

    track = frame_by_frame_tracker(TrackSetup.from_options(fr.features_path, fr.camera_path, detector=detector))
    track(fr.pixels[-1].astype(np.float32), fr.camera, 0.0)
    out = []
    for img in fr.pixels[:-1]:
        t = time.perf_counter()
        track(img.astype(np.float32), fr.camera, 0.0)
        out.append(1e3 * (time.perf_counter() - t))
    return np.array(out)


def _independent_latencies(fr, extra: list[str], gap_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Each frame sent alone, ``gap_s`` apart, to a fresh server: (send → answer ms, the server's
    own ms, the server's own ms less its tracking (``latency_ms − track_ms``: the queue, the CRC,
    decoding, composing the answer), the answers' statuses)."""
    server = Server(["--features", str(fr.features_path), "--camera", str(fr.camera_path), *extra])
    try:
        client = recording_client(server.port)
        # warm-up on a frame of its own (imports, first allocations): every measured frame then
        # follows an unrelated one, as after the C-arm moved
        closed_loop(client, fr.pixels[-1:], fr.camera, 1, 0.0)
        shots = fr.pixels[:-1]
        lat, _ = open_loop(client, shots, fr.camera, 1.0 / gap_s, len(shots), 1000.0)
        own = _server_latency(client, 1000.0, 1000.0 + len(shots))
        answers = [m for m in client.incoming_messages.log if m.timestamp >= 1000.0]
        added = np.array([float(m.metadata["latency_ms"]) - float(m.metadata["track_ms"]) for m in answers])
        status = [m.metadata.get("status", "?") for m in answers]
        client.stop()
    finally:
        server.interrupt()
    return lat, own, added, status


def independent_run(a: argparse.Namespace) -> None:
    """Unrelated frames (a C-arm moved between shots), one every ``gap`` s: the run tracker and
    ``--independent`` against ``track_image`` on one image."""
    from igt_support import rendered_frames

    fr = rendered_frames(
        Path("outputs/bench_live_independent"), a.count + 1, shape=(a.size, a.size), design=a.design, seed=11
    )
    print(
        f"independent frames: {a.design}, {a.count} {a.size}² frames at unrelated workspace poses, "
        f"one every {a.gap:g} s"
    )
    base = track_command_ms(fr, a.detector)
    print(f"bound: `track` on one image (its own path and settings), in-process: {_stats(base)}")
    for label, extra in (("run tracker (default)", []), ("--independent", ["--independent"])):
        lat, own, added, status = _independent_latencies(fr, ["--detector", a.detector, *extra], a.gap)
        kinds = {s: status.count(s) for s in sorted(set(status))}
        print(
            f"serve, {label}: {len(lat)} answered {kinds}; send → TRANSFORM {_stats(lat)}; in the server "
            f"(received → queued) {_stats(own)}, of which not tracking (queue, CRC, decode, answer) {_stats(added)}; "
            f"p50 / track p50 {np.median(lat) / np.median(base):.2f}, "
            f"p99 / track p99 {np.percentile(lat, 99) / np.percentile(base, 99):.2f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", default="ftrac_2005")
    ap.add_argument("--size", type=int, default=1024, help="frame side, pixels")
    ap.add_argument("--frames", choices=["smooth", "independent", "both"], default="both")
    ap.add_argument("--distinct", type=int, default=60, help="frames of the swing, sent forward then backward")
    ap.add_argument("--independent", action="store_true", help="smooth run: the server tracks every frame alone")
    ap.add_argument("--seconds", type=float, default=10.0, help="sending time per rate")
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument(
        "--detector",
        choices=["auto", "learned", "classical"],
        default="auto",
        help="serve --detector, and the baselines'",
    )
    ap.add_argument("--count", type=int, default=30, help="independent frames")
    ap.add_argument("--gap", type=float, default=0.5, help="seconds between independent frames")
    a = ap.parse_args()
    print(f"{machine()}; shared 2-core machine: figures are inflated by the other jobs' load")
    if a.frames in ("smooth", "both"):
        smooth_run(a)
    if a.frames in ("independent", "both"):
        independent_run(a)


if __name__ == "__main__":
    main()
