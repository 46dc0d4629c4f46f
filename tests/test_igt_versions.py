"""OpenIGTLink by the peer's header version: ``serve`` answers a version-1 client (the reference
library 1.x, older PLUS builds) with plain version-1 messages — a TRANSFORM for a frame with a
pose, a STATUS ``NoPose`` for one without — and a version-2 client as before, upgrading a
connection when its client does (PLUS's ``ClientHeaderVersion`` rule); ``push`` speaks the
server's version. The version-1 client here is written from the protocol alone: it packs its
IMAGE by hand, unpacks every reply by the 58-byte header and checks the CRC-64 itself. The
summary's counters are hammered from threads."""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from igt_support import (
    HEADER,
    ROOT,
    Server,
    crc64,
    image_message,
    read_reply,
    recording_client,
    rendered_frames,
    wait_for,
)

from ftrac_design.cli.main import main
from ftrac_design.igt import link
from ftrac_design.igt.frames import in_space, pose_matrix

pyigtl = pytest.importorskip("pyigtl")


def test_our_crc_is_the_protocols():
    assert crc64(b"123456789") == 0x6C40DF5F0B497347  # ECMA-182's check value
    body = bytes(range(256)) * 3
    assert crc64(body) == link.crc64(body)


def v1_image(
    pixels: np.ndarray, timestamp: float, spacing: float, device: str = "Image", bad_crc: bool = False
) -> bytes:
    """An IMAGE message in header version 1, packed by hand: the 72-byte image header (version 1,
    one uint16 component, big-endian, LPS, size, the i/j/k axes scaled by the spacing, the
    centre, the whole volume as its subvolume), then the pixels row by row."""
    h, w = pixels.shape
    head = struct.pack(">HBBBBHHH", 1, 1, 5, 1, 2, w, h, 1)
    head += struct.pack(">12f", spacing, 0, 0, 0, spacing, 0, 0, 0, 1, 0, 0, 0)
    head += struct.pack(">6H", 0, 0, 0, w, h, 1)
    body = head + pixels.astype(">u2").tobytes()
    sec = int(timestamp)
    frac = int((timestamp - sec) * 2**32)
    crc = crc64(body) ^ (1 if bad_crc else 0)
    return HEADER.pack(1, b"IMAGE", b"Image", sec, frac, len(body), crc) + body


def transform_matrix(content: bytes) -> np.ndarray:
    """The 4×4 of a TRANSFORM's 48-byte content (R column by column, then the translation)."""
    v = struct.unpack(">12f", content)
    M = np.eye(4)
    M[:3, :3] = np.array(v[:9]).reshape(3, 3).T
    M[:3, 3] = v[9:]
    return M


def status_fields(content: bytes) -> tuple[int, str, str]:
    code, _, name = struct.unpack(">Hq20s", content[:30])
    return code, name.rstrip(b"\0").decode(), content[30:].split(b"\0")[0].decode()


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    return rendered_frames(tmp_path_factory.mktemp("igtv"), 2)


@pytest.fixture(scope="module")
def offline(frames, tmp_path_factory):
    d = tmp_path_factory.mktemp("offline")
    np.save(d / "run.npy", frames.pixels)
    args = ["track", "--features", str(frames.features_path), str(d / "run.npy"), "--camera", str(frames.camera_path)]
    assert main([*args, "--independent", "-o", str(d / "poses.jsonl")]) == 0
    return [json.loads(x) for x in (d / "poses.jsonl").read_text().splitlines()]


def _stop(server: Server) -> str:
    rc, out, err = server.interrupt()
    assert rc == 0 and "Traceback" not in err, err
    return out


def test_a_version_1_client_gets_version_1_answers_and_upgrades_when_it_does(frames, offline):
    server = Server(["--features", str(frames.features_path), "--camera", str(frames.camera_path)])
    blank = np.full_like(frames.pixels[0], 30000)
    try:
        with socket.create_connection(("127.0.0.1", server.port), timeout=60) as s:
            s.sendall(v1_image(frames.pixels[0], 1000.25, 0.44))
            r = read_reply(s)
            assert (r["version"], r["type"], r["device"], len(r["content"])) == (1, "TRANSFORM", "FiducialToCArm", 48)
            assert abs(r["timestamp"] - 1000.25) < 1e-6
            want = in_space(pose_matrix(offline[0]["rotation"], offline[0]["translation_mm"]), "ras")
            assert np.allclose(transform_matrix(r["content"]), want, rtol=0, atol=1e-4 * np.abs(want).max())
            # a frame without a pose: no TRANSFORM (an identity would put the fiducial at the source), a STATUS
            s.sendall(v1_image(blank, 1001.5, 0.44))
            r = read_reply(s)
            assert (r["version"], r["type"], r["device"]) == (1, "STATUS", "FiducialToCArm")
            code, name, text = status_fields(r["content"])
            assert (code, name) == (link.STATUS_NOT_FOUND, "NoPose") and text.startswith("frame 1: ")
            assert abs(r["timestamp"] - 1001.5) < 1e-6
            s.sendall(v1_image(frames.pixels[1], 1002.0, 0.44, bad_crc=True))
            r = read_reply(s)
            assert (r["version"], r["type"]) == (1, "STATUS")
            assert status_fields(r["content"])[0] == link.STATUS_CHECKSUM_ERROR
            # the client speaks version 2: so does the server from then on, even when it goes back to 1
            s.sendall(image_message(frames.pixels[1], frames.camera, 1003.0, {}).pack())
            r = read_reply(s)
            assert (r["version"], r["type"], len(r["content"])) == (2, "TRANSFORM", 48) and r["metadata"]["count"] > 5
            s.sendall(v1_image(frames.pixels[0], 1004.0, 0.44))
            assert read_reply(s)["version"] == 2
        assert wait_for(lambda: any("closed" in line for line in server.lines), 10)
    finally:
        out = _stop(server)
    assert "answered in header version 2" in out


def _pyigtl_client_versions(server_port: int, frames, version: int) -> list:
    client = recording_client(server_port)
    try:
        msg = image_message(frames.pixels[0], frames.camera, 1000.0, {} if version == 1 else None)
        msg.header_version = version
        client.send_message(msg)
        assert wait_for(lambda: client.incoming_messages.log, 60)
        return list(client.incoming_messages.log)
    finally:
        client.stop()


@pytest.mark.parametrize("version", [1, 2])
def test_pyigtl_clients_of_either_version_get_their_own(frames, offline, version):
    server = Server(["--features", str(frames.features_path), "--camera", str(frames.camera_path)])
    try:
        (answer,) = _pyigtl_client_versions(server.port, frames, version)
    finally:
        _stop(server)
    assert answer.message_type == "TRANSFORM" and answer.header_version == version
    want = in_space(pose_matrix(offline[0]["rotation"], offline[0]["translation_mm"]), "ras")
    assert np.allclose(answer.matrix, want, rtol=0, atol=1e-4 * np.abs(want).max())
    if version == 1:
        assert answer.metadata == {}
    else:
        R, t = link.pose_from_metadata(answer.metadata)
        assert np.array_equal(t, offline[0]["translation_mm"]) and np.array_equal(R, offline[0]["rotation"])


def test_the_answer_of_a_frame_in_each_version():
    pose = {"converged": True, "rotation": np.eye(3).tolist(), "translation_mm": [1.0, 2.0, 600.0], "status": "tracked"}
    lost = {"converged": False, "error": "no fiducial found", "status": "lost"}
    failed = {"converged": False, "error": "internal error: boom", "status": "error"}
    args = ("FiducialToCArm", "ras", 1000.0, {"frame": "7"})
    (v2,) = link.answer_messages(pose, *args, version=2)
    (v1,) = link.answer_messages(pose, *args, version=1)
    assert (v2.header_version, v2.metadata["TransformStatus"]) == (2, "OK") and v1.header_version == 1
    assert v1.metadata == {} and np.array_equal(v1.matrix, v2.matrix)
    (inv2,) = link.answer_messages(lost, *args, version=2)
    assert inv2.metadata["TransformStatus"] == "INVALID" and link.answer_messages(lost, *args, 2, valid_only=True) == []
    (st,) = link.answer_messages(lost, *args, version=1)
    assert (st.message_type, st.code, st.error_name, st.status_string) == (
        "STATUS",
        link.STATUS_NOT_FOUND,
        "NoPose",
        "frame 7: no fiducial found",
    )
    assert link.answer_messages(lost, *args, 1, valid_only=True)[0].message_type == "STATUS"
    assert link.answer_messages(failed, *args, version=1)[0].code == link.STATUS_UNKNOWN_ERROR
    packed = link.packed(link.transform_message(pose, *args[:3], {"a": "b"}), 1)
    assert struct.unpack(">H", packed[:2])[0] == 1 and len(packed) == 58 + 48


def test_a_peers_version_rises_to_the_highest_it_sent_and_no_further():
    peer = link.PeerVersion()
    assert peer.version == 1 and peer.heard(1) == 1 and peer.heard(2) == 2 and peer.heard(1) == 2
    assert link.PeerVersion().heard(3) == 2


class _FakeClient:
    def __init__(self, versions):
        self.incoming_messages = {f"d{k}": type("M", (), {"header_version": v})() for k, v in enumerate(versions)}


def test_push_speaks_the_servers_version_once_it_has_sent_one():
    from ftrac_design.workflows.serve import server_version

    assert server_version(_FakeClient([]), 2) == 2 and server_version(_FakeClient([]), 1) == 1
    assert server_version(_FakeClient([1]), 2) == 1 and server_version(_FakeClient([1, 2]), 1) == 2


def test_push_in_version_1_sends_plain_transforms_and_a_status_for_a_lost_pose(offline, tmp_path):
    from igt_support import _Recorder

    run = [offline[0], {"format": "ftrac-pose", "version": 1, "converged": False, "error": "lost"}]
    path = tmp_path / "run.jsonl"
    path.write_text("".join(json.dumps(d) + "\n" for d in run))
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    pyigtl.messages.message_type_to_class_constructor.setdefault("STATUS", link.status_message_class())
    server = pyigtl.OpenIGTLinkServer(port, start_now=False)
    server.incoming_messages = _Recorder()
    server.start()
    try:
        res = subprocess.run(
            [sys.executable, "-m", "ftrac_design.cli.main", "push", str(path), "--port", str(port)]
            + ["--rate", "20", "--header-version", "1"],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=60,
            env={"PYTHONPATH": str(ROOT), "PATH": ""},
        )
        assert res.returncode == 0, res.stderr
        assert wait_for(lambda: len(server.incoming_messages.log) == 2, 10)
    finally:
        server.stop()
        import signal

        for sig, handler in server._previous_signal_handlers.items():
            signal.signal(sig, handler)
    tf, st = server.incoming_messages.log
    assert (tf.message_type, tf.header_version, tf.metadata) == ("TRANSFORM", 1, {})
    assert (st.message_type, st.header_version, st.error_name, st.device_name) == (
        "STATUS",
        1,
        "NoPose",
        "FiducialToCArm",
    )


def test_the_summary_counts_exactly_when_both_threads_count_at_once():
    """The socket thread (a client gone: replies undelivered) and the tracking loop (frames of a
    closed connection) count the same total at once: no increment may be lost."""
    from ftrac_design.workflows.serve import IgtlServer, InboxItem, ServeOptions, _answer_until_stopped

    n_stale, n_threads, per_thread = 400, 4, 3000
    server = IgtlServer(ServeOptions(port=0, queue=n_stale, report_s=0))
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: a lost update shows
    try:
        raw = link.RawMessage(2, "IMAGE", "Image", {"timestamp": 0.0, "device_name": "Image"}, bytearray(), 0)
        for k in range(n_stale):
            server.inbox.put(InboxItem(raw, 99, k, time.perf_counter()))  # a connection long closed
        stop = threading.Event()
        loop = threading.Thread(target=_answer_until_stopped, args=(server, None, None, stop))
        msg = link.status_message(link.STATUS_OK, "x", "d")

        stale = InboxItem(raw, 97, 0, 0.0)

        def hammer():
            for k in range(per_thread):
                if k % 2:
                    server.reply(msg, 98)
                else:
                    server.discard_stale(stale)
                server.summary.count(answered=1)

        workers = [threading.Thread(target=hammer) for _ in range(n_threads)]
        loop.start()
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        assert wait_for(lambda: server.summary.undelivered >= n_stale + n_threads * per_thread, 30)
        stop.set()
        loop.join(5)
    finally:
        sys.setswitchinterval(switch)
        server.close()
    assert server.summary.undelivered == n_stale + n_threads * per_thread
    assert server.summary.answered == n_threads * per_thread


def test_the_tracking_loops_count_of_a_closed_connections_frame_takes_the_summarys_lock():
    """Deterministically: while the summary's lock is held, the loop's path cannot count."""
    from ftrac_design.workflows.serve import IgtlServer, InboxItem, ServeOptions

    server = IgtlServer(ServeOptions(port=0, report_s=0))
    try:
        raw = link.RawMessage(2, "IMAGE", "Image", {"timestamp": 0.0, "device_name": "Image"}, bytearray(), 0)
        t = threading.Thread(target=server.discard_stale, args=(InboxItem(raw, 5, 0, 0.0),))
        with server.summary._lock:
            t.start()
            t.join(0.2)
            assert t.is_alive() and server.summary.undelivered == 0  # waiting for the lock
        t.join(10)
        assert server.summary.undelivered == 1
    finally:
        server.close()
