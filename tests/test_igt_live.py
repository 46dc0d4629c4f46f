"""``ftrac-design serve`` and ``push`` with real pyigtl peers on localhost.

300 rendered 512² frames of ftrac_2005 (30 distinct poses, sent ten times over) go to a
``serve`` subprocess at 30 frames/s: each is answered by a TRANSFORM or counted as dropped,
exactly, and every pose equals offline ``track`` of the same frame within 1e-6; a client
disconnects mid-run and another connects; malformed messages get STATUS errors and the server
goes on; Ctrl-C stops it with a summary and exit 0. ``push`` sends a run to a pyigtl server.
"""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from igt_support import (
    HEADER,
    ROOT,
    Server,
    image_message,
    read_reply,
    recording_client,
    rendered_frames,
    send_frames,
    wait_for,
)

from ftrac_design.cli.main import main
from ftrac_design.igt import link
from ftrac_design.igt.frames import in_space, pose_matrix

pyigtl = pytest.importorskip("pyigtl")

N_DISTINCT = 30


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    return rendered_frames(tmp_path_factory.mktemp("igt"), N_DISTINCT)


@pytest.fixture(scope="module")
def offline(frames, tmp_path_factory):
    """``ftrac-design track --independent`` of the same frames (a (n, H, W) .npy run, --camera): one
    pose each, every frame alone (the workspace poses are unrelated: not a run to track along)."""
    d = tmp_path_factory.mktemp("offline")
    np.save(d / "run.npy", frames.pixels)
    main(
        [
            "track",
            "--features",
            str(frames.features_path),
            str(d / "run.npy"),
            "--camera",
            str(frames.camera_path),
            "--independent",
            "-o",
            str(d / "poses.jsonl"),
        ]
    )
    return [json.loads(x) for x in (d / "poses.jsonl").read_text().splitlines()]


def _camera_metadata(frames) -> dict[str, str]:
    return {"camera": json.dumps(frames.camera.to_dict())}


def _answers(client) -> list:
    return [m for m in client.incoming_messages.log if m.message_type == "TRANSFORM"]


def _stop(server: Server) -> str:
    rc, out, err = server.interrupt()
    assert rc == 0 and "Traceback" not in err, err
    assert out.strip().splitlines()[-1].startswith("stopped: ")
    return out


def test_300_frames_at_30_per_second_answered_or_counted_and_equal_to_offline_track(frames, offline):
    server = Server(["--features", str(frames.features_path), "--independent"])
    try:
        client = recording_client(server.port)
        n = 10 * N_DISTINCT
        t0, stamps = time.perf_counter(), []
        for k in range(n):
            wait = t0 + k / 30.0 - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            stamps.append(1000.0 + k)
            client.send_message(
                image_message(frames.pixels[k % N_DISTINCT], frames.camera, stamps[-1], _camera_metadata(frames)),
                wait=False,
            )
        assert wait_for(lambda: _answers(client) and _answers(client)[-1].timestamp == stamps[-1], 60)
        client.stop()
    finally:
        out = _stop(server)
    answers = _answers(client)
    index = [int(m.metadata["frame"]) for m in answers]
    # answers come in order, one per answered frame; the last frame is always answered and its
    # answer carries the final drop count: answered + dropped = sent, exactly
    assert index == sorted(set(index)) and index[-1] == n - 1
    assert len(answers) + int(answers[-1].metadata["dropped"]) == n
    assert f"{n} frames received, {len(answers)} answered" in out
    assert [m.timestamp for m in answers] == [stamps[k] for k in index]
    for m, k in zip(answers, index):
        ref = offline[k % N_DISTINCT]
        assert m.device_name == "FiducialToCArm" and m.metadata["TransformStatus"] == "OK" and ref["converged"]
        R, t = link.pose_from_metadata(m.metadata)
        assert np.abs(R - np.array(ref["rotation"])).max() < 1e-6
        assert np.abs(t - np.array(ref["translation_mm"])).max() < 1e-6
        assert np.allclose(json.loads(m.metadata["covariance"]), ref["covariance"], rtol=1e-6, atol=1e-12)
        # the float32 matrix is the RAS form of the same pose
        want = in_space(pose_matrix(ref["rotation"], ref["translation_mm"]), "ras")
        assert np.allclose(m.matrix, want, rtol=0, atol=1e-4 * np.abs(want).max())
        assert m.metadata["space"] == "RAS" and float(m.metadata["latency_ms"]) >= float(m.metadata["track_ms"])


def test_a_client_disconnects_mid_run_and_another_connects(frames, offline):
    server = Server(
        ["--features", str(frames.features_path), "--camera", str(frames.camera_path), "--queue", "1", "--independent"]
    )
    try:
        first = recording_client(server.port)
        send_frames(first, frames.pixels[:12], frames.camera, 30.0)
        first.stop()  # gone mid-run, its last frames unanswered
        second = recording_client(server.port)
        stamps = send_frames(second, frames.pixels[12:24], frames.camera, 30.0, start_index=100)
        assert wait_for(lambda: _answers(second) and _answers(second)[-1].timestamp == stamps[-1], 60)
        second.stop()
    finally:
        out = _stop(server)
    answers = _answers(second)
    index = [int(m.metadata["frame"]) for m in answers]
    # the second connection counts its own frames from 0, exactly accounted for
    assert index[-1] == 11 and len(answers) + int(answers[-1].metadata["dropped"]) == 12
    for m, k in zip(answers, index):
        R, t = link.pose_from_metadata(m.metadata)
        assert np.abs(t - np.array(offline[12 + k]["translation_mm"])).max() < 1e-6
    assert "2 connections, 24 frames received" in out and "(connection 2)" in out


def _raw(mtype: str, device: str, body: bytes, version: int = 2, crc: int | None = None) -> bytes:
    from pyigtl.messages import CRC64

    return (
        HEADER.pack(version, mtype.encode(), device.encode(), 1000, 0, len(body), CRC64(body) if crc is None else crc)
        + body
    )


def _read_reply(sock: socket.socket) -> tuple[str, bytes]:
    """(type, content) of the next message, decoded by hand from the protocol's header."""
    r = read_reply(sock)
    return r["type"], r["content"]


def _status_code(reply: tuple[str, bytes]) -> tuple[int, str]:
    mtype, body = reply
    assert mtype == "STATUS"
    code = struct.unpack(">H", body[:2])[0]
    return code, body[30:].split(b"\0")[0].decode()


def test_malformed_messages_get_an_error_status_and_the_server_goes_on(frames):
    server = Server(["--features", str(frames.features_path), "--host", "0.0.0.0"])
    try:
        good = image_message(frames.pixels[0], frames.camera, 1000.0, _camera_metadata(frames)).pack()
        no_camera = image_message(frames.pixels[0], frames.camera, 1000.0, {}).pack()
        with socket.create_connection(("127.0.0.1", server.port), timeout=30) as s:
            s.sendall(_raw("IMAGE", "Image", b"\0" * 10))  # body too short
            assert _status_code(_read_reply(s))[0] == link.STATUS_INVALID_PACKET
            s.sendall(good[:50] + struct.pack(">Q", 12345) + good[58:])  # CRC mismatch
            assert _status_code(_read_reply(s))[0] == link.STATUS_CHECKSUM_ERROR
            s.sendall(pyigtl.StringMessage("hello", device_name="Text").pack())  # not an IMAGE
            assert _status_code(_read_reply(s))[0] == link.STATUS_UNKNOWN_INSTRUCTION
            s.sendall(no_camera)  # no camera anywhere
            code, text = _status_code(_read_reply(s))
            assert code == link.STATUS_CONFIGURATION_ERROR and "focal_length_mm" in text
            s.sendall(good)  # the same link still works
            mtype, body = _read_reply(s)
            assert mtype == "TRANSFORM" and len(body) == 48
            s.sendall(_raw("IMAGE", "Image", b"", version=7))  # a header not to trust
            code, text = _status_code(_read_reply(s))
            assert code == link.STATUS_INVALID_PACKET and "closing" in text
            assert s.recv(1) == b""
        client = recording_client(server.port)  # and the server listens on
        client.send_message(image_message(frames.pixels[1], frames.camera, 1001.0, _camera_metadata(frames)))
        assert wait_for(lambda: _answers(client), 30)
        client.stop()
    finally:
        out = _stop(server)
    assert "every interface" in out.splitlines()[0] and "5 bad messages" in out


def test_push_sends_a_run_to_a_listening_server(offline, tmp_path):
    from igt_support import _Recorder

    run = offline[:5] + [{"format": "ftrac-pose", "version": 1, "converged": False, "error": "lost"}]
    path = tmp_path / "run.jsonl"
    path.write_text("".join(json.dumps(d) + "\n" for d in run))
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = pyigtl.OpenIGTLinkServer(port, start_now=False)
    server.incoming_messages = _Recorder()
    server.start()
    try:
        res = subprocess.run(
            [sys.executable, "-m", "ftrac_design.cli.main", "push", str(path), "--port", str(port), "--rate", "20"],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=60,
            env={"PYTHONPATH": str(ROOT), "PATH": ""},
        )
        assert res.returncode == 0, res.stderr
        assert wait_for(lambda: len(server.incoming_messages.log) == len(run), 10)
    finally:
        server.stop()
        for sig, handler in server._previous_signal_handlers.items():
            import signal

            signal.signal(sig, handler)
    got = server.incoming_messages.log
    for m, ref in zip(got[:5], run[:5]):
        R, t = link.pose_from_metadata(m.metadata)
        assert np.array_equal(t, ref["translation_mm"]) and np.array_equal(R, ref["rotation"])
        want = in_space(pose_matrix(ref["rotation"], ref["translation_mm"]), "ras")
        assert np.allclose(m.matrix, want, rtol=0, atol=1e-4 * np.abs(want).max())
    assert got[5].metadata["TransformStatus"] == "INVALID" and np.array_equal(got[5].matrix, np.eye(4))


def test_push_with_no_server_exits_2_with_one_line(tmp_path, offline, capsys):
    path = tmp_path / "run.jsonl"
    path.write_text(json.dumps(offline[0]) + "\n")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    assert main(["push", str(path), "--port", str(port), "--timeout", "0.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--port" in err


def test_the_camera_from_an_image_messages_spacing_and_metadata(frames):
    msg = image_message(
        frames.pixels[0], frames.camera, 1000.0, {"focal_length_mm": "1000", "principal_point_px": "250 260.5"}
    )
    back = pyigtl.ImageMessage()
    packed = msg.pack()
    back.unpack(pyigtl.MessageBase.parse_header(packed[:58]), packed[58:])
    pix = link.image_pixels(back)
    cam, source = link.image_camera(back, pix.shape, None)
    assert pix.shape == (512, 512) and np.array_equal(pix, frames.pixels[0])
    assert cam.focal_length_mm == 1000 and cam.principal_point_px == (250.0, 260.5)
    assert np.allclose(cam.pixel_size_mm, (0.44, 0.44), rtol=1e-7) and "spacing" in source
    back.metadata = {"focal_length_mm": "1000"}
    assert link.image_camera(back, pix.shape, None)[0].principal_point_px == (255.5, 255.5)
    assert link.image_camera(back, pix.shape, frames.camera)[0] == frames.camera


def _raw_image(timestamp: float) -> link.RawMessage:
    return link.RawMessage(2, "IMAGE", "Image", {"timestamp": timestamp, "device_name": "Image"}, bytearray(), 0)


def test_the_inbox_drops_the_oldest_and_counts_per_connection():
    from ftrac_design.workflows.serve import FrameInbox, InboxItem

    inbox = FrameInbox(2)
    for k in range(5):
        inbox.put(InboxItem(_raw_image(1000.0 + k), 1 + (k == 4), k, 0.0))
    assert inbox.dropped == {1: 3}
    assert [inbox.get(0).timestamp, inbox.get(0).timestamp, inbox.get(0.01)] == [1003.0, 1004.0, None]
    inbox.put(InboxItem(_raw_image(2000.0), 3, 0, 0.0))
    assert inbox.discard_connection(3) == 1 and inbox.get(0.01) is None


def test_a_plugged_in_tracker_gets_each_frame_and_its_errors_become_invalid_answers(frames):
    """The seam the run tracker uses: the factory's tracker sees every frame in order with its
    camera and timestamp; a pose it returns is sent, an exception or a malformed pose becomes an
    INVALID answer saying why, and the server goes on."""
    import threading

    from ftrac_design.workflows.serve import ServeOptions, serve

    seen, ports = [], []
    M = in_space(pose_matrix(np.eye(3), [1.0, 2.0, 600.0]), "lps")

    def factory(setup):
        assert setup == "the setup"

        def track(image, camera, time_s):
            seen.append((image.shape, image.dtype, camera, time_s))
            k = len(seen) - 1
            if k == 1:
                raise RuntimeError("lost it")
            if k == 2:
                return {"converged": True, "rotation": [[1, 0]], "translation_mm": [0, 0, 1]}
            return {
                "converged": True,
                "rotation": M[:3, :3].tolist(),
                "translation_mm": M[:3, 3].tolist(),
                "status": "tracked",
            }

        return track

    stop = threading.Event()
    got: list = []

    def drive():
        try:
            wait_for(lambda: ports, 30)
            client = recording_client(ports[0])
            for k in range(4):  # one at a time: none dropped
                client.send_message(
                    image_message(frames.pixels[k], frames.camera, 1000.0 + k, _camera_metadata(frames)), wait=False
                )
                wait_for(lambda n=k + 1: len(_answers(client)) == n, 30)
            got.extend(_answers(client))
            client.stop()
        finally:
            stop.set()

    threading.Thread(target=drive, daemon=True).start()
    summary = serve(
        "the setup",
        ServeOptions(port=0, space="lps"),
        factory=factory,
        stop=stop,
        on_listen=lambda s: ports.append(s.port),
    )
    assert [s[3] for s in seen] == [1000.0, 1001.0, 1002.0, 1003.0]
    assert all(s[0] == (512, 512) and s[1] == np.float32 and s[2] == frames.camera for s in seen)
    assert [m.metadata["TransformStatus"] for m in got] == ["OK", "INVALID", "INVALID", "OK"]
    assert "lost it" in got[1].metadata["error"] and got[1].metadata["status"] == "error"
    assert "the tracker's pose" in got[2].metadata["error"]
    assert np.allclose(got[0].matrix, M, atol=1e-4) and np.array_equal(got[1].matrix, np.eye(4))
    assert summary.received == 4 and summary.answered == 4 and summary.tracked == 2


def test_serve_bad_input_exits_2_with_one_line(frames, tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        cases = [
            (["--features", str(tmp_path / "missing.json")], "missing.json"),
            (["--features", str(frames.features_path), "--name", "Fiducial-CArm"], "--name"),
            (["--features", str(frames.features_path), "--camera", str(frames.features_path)], "camera"),
            (["--features", str(frames.features_path), "--port", str(port)], "--port"),
        ]
        for args, words in cases:
            assert main(["serve", *args]) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and words in err and "Traceback" not in err


def test_ctrl_c_while_frames_flow_stops_the_server_cleanly(frames):
    import threading

    server = Server(["--features", str(frames.features_path), "--camera", str(frames.camera_path)])
    client = recording_client(server.port)
    flowing = threading.Event()

    def flood():
        k = 0
        while not flowing.is_set():
            client.send_message(image_message(frames.pixels[k % N_DISTINCT], frames.camera, 1000.0 + k), wait=False)
            k += 1
            time.sleep(1 / 30)

    sender = threading.Thread(target=flood, daemon=True)
    sender.start()
    try:
        assert wait_for(lambda: len(_answers(client)) >= 2, 60)
        started = time.monotonic()
        out = _stop(server)  # SIGINT mid-stream, the tracker busy
        assert time.monotonic() - started < 60 and "1 connections" in out
    finally:
        flowing.set()
        sender.join(5)
        client.stop()
        server.kill()


def test_sigterm_stops_the_server_cleanly(frames):
    import signal

    server = Server(["--features", str(frames.features_path)])
    server.proc.send_signal(signal.SIGTERM)
    rc = server.proc.wait(120)
    server._reader.join(5)
    assert rc == 0 and "".join(server.lines).strip().splitlines()[-1].startswith("stopped: 0 connections")


def test_valid_only_sends_nothing_for_a_frame_without_a_pose(frames):
    import threading

    from ftrac_design.workflows.serve import ServeOptions, serve

    servers, got = [], []
    stop = threading.Event()

    def factory(setup):
        def track(image, camera, time_s):
            if time_s == 1000.0:
                return {"converged": False, "error": "no fiducial"}
            return {"converged": True, "rotation": np.eye(3).tolist(), "translation_mm": [0.0, 0.0, 600.0]}

        return track

    def drive():
        try:
            wait_for(lambda: servers, 30)
            client = recording_client(servers[0].port)
            for k in range(2):
                client.send_message(
                    image_message(frames.pixels[k], frames.camera, 1000.0 + k, _camera_metadata(frames)), wait=False
                )
                wait_for(lambda n=k + 1: servers[0].summary.answered == n, 30)
            wait_for(lambda: _answers(client), 30)
            got.extend(_answers(client))
            client.stop()
        finally:
            stop.set()

    threading.Thread(target=drive, daemon=True).start()
    summary = serve(None, ServeOptions(port=0, valid_only=True), factory=factory, stop=stop, on_listen=servers.append)
    assert [m.timestamp for m in got] == [1001.0] and summary.answered == 2 and summary.tracked == 1


def test_push_paces_by_time_s_else_the_rate():
    from ftrac_design.pose import Pose, Provenance, TrackedPose
    from ftrac_design.workflows.serve import send_times

    def rec(t):
        return TrackedPose(Pose(np.eye(3), np.zeros(3), True, 0.0, None, {}, 0), provenance=Provenance(time_s=t))

    assert send_times([rec(5.0), rec(5.5), rec(7.0)], None) == [5.0, 5.5, 7.0]
    assert send_times([rec(5.0), rec(5.5)], 4.0) == [0.0, 0.25]
    assert send_times([rec(5.0), rec(None)], None) == [0.0, 1 / 30]
    assert send_times([rec(5.0), rec(4.0)], None) == [0.0, 1 / 30]


@pytest.mark.parametrize("argv", [["serve", "--features", "F.json"], ["push", "P.jsonl"]])
def test_without_pyigtl_the_live_commands_stop_with_one_line_naming_the_extra(argv, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pyigtl", None)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ftrac_design[live]" in err and "'pyigtl'" in err


def test_a_run_served_frame_after_frame_equals_offline_track_of_the_run(tmp_path):
    """The default tracker follows the fiducial from frame to frame as `track` does a run: with
    nothing dropped (each frame sent after the last answer), every served pose equals the run
    tracker's on the same frames at the same times within 1e-6, and most frames are tracked, not
    re-identified."""
    from ftrac_design.design import load_design
    from ftrac_design.design.presets import PRESETS_DIR
    from ftrac_design.features import compute_features, write_features
    from ftrac_design.pose import Camera
    from ftrac_design.pose.simulate import Workspace
    from ftrac_design.tracking import RunTracker
    from ftrac_design.xray import ImagingModel
    from ftrac_design.xray.sweep import render_sweep

    shape, n = (512, 512), 8
    cam = Camera(1000.0, (0.44, 0.44), ((shape[1] - 1) / 2, (shape[0] - 1) / 2))
    features = compute_features(load_design(PRESETS_DIR / "ftrac_2005.toml"))
    R0, t0 = Workspace(cone_deg=10.0, lateral_mm=5.0).sample(
        1, features.nominal_beam_direction, np.random.default_rng(5)
    )
    run = render_sweep(
        features,
        R0[0],
        t0[0],
        n,
        cam,
        ImagingModel(image_shape=shape),
        seed=5,
        anatomy_strength=0.6,
        margin_px=96,
        swing_deg=8.0,
        period_frames=60.0,
        tilt_deg=3.0,
        tilt_period_frames=41.0,
        drift_mm=(4.0, 3.0, 2.0),
    )
    fpath = write_features(tmp_path / "f.json", features)
    cpath = tmp_path / "camera.json"
    cpath.write_text(json.dumps(cam.to_dict()))
    pixels = np.asarray(run.raw, np.uint16)
    # 32 frames/s: times exact in OpenIGTLink's 32.32 fixed point, so the server predicts from the
    # very times the reference does (a run's prediction scales by them)
    times = [1000.0 + k / 32.0 for k in range(n)]
    server = Server(["--features", str(fpath), "--camera", str(cpath), "--queue", "4"])
    try:
        client = recording_client(server.port)
        for k in range(n):
            client.send_message(image_message(pixels[k], cam, times[k]), wait=False)
            assert wait_for(lambda k=k: len(_answers(client)) == k + 1, 60)
        client.stop()
    finally:
        _stop(server)
    answers = _answers(client)
    assert [int(m.metadata["dropped"]) for m in answers] == [0] * n
    assert [m.timestamp for m in answers] == times
    offline = RunTracker(features, cam)
    ref = [offline.track(pixels[k], cam, times[k]) for k in range(n)]
    statuses = [r["status"] for r in ref]
    assert statuses.count("tracked") >= n - 2, statuses
    for m, r in zip(answers, ref):
        R, t = link.pose_from_metadata(m.metadata)
        assert m.metadata["status"] == r["status"]
        assert np.abs(R - np.array(r["rotation"])).max() < 1e-6
        assert np.abs(t - np.array(r["translation_mm"])).max() < 1e-6
