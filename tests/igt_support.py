"""Shared by tests/test_igt_*.py and benchmarks/live_latency.py: rendered frames of ftrac_2005,
an ``ftrac-design serve`` subprocess on a free port, and a pyigtl client that keeps every
message it receives (pyigtl's own keeps only the latest per device name)."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ftrac_design.design import load_design
from ftrac_design.design.presets import PRESETS_DIR
from ftrac_design.features import compute_features, write_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.xray import ImagingModel, render

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Frames:
    """Rendered raw frames (n, H, W) uint16 of one design at workspace poses, the camera they
    were rendered with (principal point at the image centre) and the features file."""

    pixels: np.ndarray
    camera: Camera
    features_path: Path
    camera_path: Path


def rendered_frames(
    out_dir: Path, n: int, shape: tuple[int, int] = (512, 512), design: str = "ftrac_2005", seed: int = 0
) -> Frames:
    """``n`` raw radiographs of ``design`` at workspace poses (seed ``seed``), 0.44 mm pixels, f = 1000 mm."""
    d = load_design(PRESETS_DIR / f"{design}.toml")
    features = compute_features(d)
    cam = Camera(1000.0, (0.44, 0.44), ((shape[1] - 1) / 2, (shape[0] - 1) / 2))
    R, t = Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(seed))
    pix = np.stack(
        [
            np.asarray(
                render(features, R[k], t[k], cam, ImagingModel(image_shape=shape), rng=np.random.default_rng(k)).raw,
                np.uint16,
            )
            for k in range(n)
        ]
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    fpath = write_features(out_dir / f"{design}.features.json", features)
    cpath = out_dir / "camera.json"
    cpath.write_text(json.dumps(cam.to_dict()))
    return Frames(pix, cam, Path(fpath), cpath)


class Server:
    """``ftrac-design serve`` in a subprocess on a free port (``--port 0``, read from its first line)."""

    def __init__(self, args: list[str], timeout_s: float = 60.0):
        env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "ftrac_design.cli.main", "serve", "--port", "0", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=ROOT,
        )
        self.lines: list[str] = []
        first = self.proc.stdout.readline()
        self.lines.append(first)
        m = re.search(r"listening on [\d.]+:(\d+)", first)
        if m is None:
            self.proc.kill()
            raise RuntimeError(f"serve did not start: {first!r} {self.proc.stderr.read()!r}")
        self.port = int(m.group(1))
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line)

    def interrupt(self, timeout_s: float = 120.0) -> tuple[int, str, str]:
        """Ctrl-C: (exit code, stdout, stderr)."""
        self.proc.send_signal(signal.SIGINT)
        rc = self.proc.wait(timeout_s)
        self._reader.join(5)
        return rc, "".join(self.lines), self.proc.stderr.read()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


class _Recorder(dict):
    """pyigtl's incoming-message store that also keeps every message in arrival order."""

    def __init__(self):
        super().__init__()
        self.log: list = []
        self.times: list[float] = []

    def __setitem__(self, key, value):
        self.times.append(time.perf_counter())
        self.log.append(value)
        super().__setitem__(key, value)


def _patient_client_class():
    from pyigtl import OpenIGTLinkClient

    class PatientClient(OpenIGTLinkClient):
        """pyigtl's client, whose socket waits 10 ms at most for anything: a 1024² frame (2 MB)
        cannot leave within that while the receiver is busy, and pyigtl then drops the link
        mid-message. This one allows a send 10 s, as a blocking sender (PLUS) does."""

        def _send_queued_message_from_socket(self, sock):
            sock.settimeout(10.0)
            try:
                return super()._send_queued_message_from_socket(sock)
            finally:
                sock.settimeout(0.01)

    return PatientClient


def recording_client(port: int, host: str = "127.0.0.1", timeout_s: float = 20.0):
    """A connected pyigtl client whose ``incoming_messages.log`` keeps every message received
    (and whose sends may take up to 10 s, see ``PatientClient``)."""
    client = _patient_client_class()(host, port, start_now=False)
    client.incoming_messages = _Recorder()
    client.start()
    deadline = time.monotonic() + timeout_s
    while not client.is_connected():
        if time.monotonic() > deadline:
            client.stop()
            raise RuntimeError(f"no connection to {host}:{port}")
        time.sleep(0.01)
    return client


def image_message(pixels: np.ndarray, camera: Camera, timestamp: float, metadata: dict[str, str] | None = None):
    """An IMAGE message of one frame as PLUS sends it: one slice (1, H, W), spacing in the
    matrix, header version 2 with ``metadata`` (default: the focal length)."""
    from pyigtl import ImageMessage

    M = np.diag([camera.pixel_size_mm[0], camera.pixel_size_mm[1], 1.0, 1.0])
    msg = ImageMessage(pixels[np.newaxis], ijk_to_world_matrix=M, timestamp=timestamp, device_name="Image")
    msg.header_version = 2
    msg.metadata = metadata if metadata is not None else {"focal_length_mm": repr(camera.focal_length_mm)}
    return msg


def send_frames(client, frames: np.ndarray, camera: Camera, rate_hz: float, start_index: int = 0) -> list[float]:
    """Send ``frames`` at ``rate_hz`` (never waiting for answers); their timestamps (k's is
    ``1000 + start_index + k``, so an answer names its frame)."""
    stamps, t0 = [], time.perf_counter()
    for k, img in enumerate(frames):
        wait = t0 + k / rate_hz - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        ts = 1000.0 + start_index + k
        client.send_message(image_message(img, camera, ts), wait=False)
        stamps.append(ts)
    return stamps


def wait_for(pred, timeout_s: float) -> bool:
    """Poll ``pred()`` every 20 ms until true or ``timeout_s``; its last value."""
    deadline = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > deadline:
            return bool(pred())
        time.sleep(0.02)
    return True


#: the protocol's 58-byte header, unpacked by hand (not by pyigtl)
HEADER = struct.Struct(">H12s20sIIQQ")  # version, type, device, seconds, fraction, body size, CRC-64
POLY = 0x42F0E1EBA9EA3693  # ECMA-182, as the protocol specifies
MASK = (1 << 64) - 1


def _table() -> list[int]:
    out = []
    for i in range(256):
        crc = i << 56
        for _ in range(8):
            crc = ((crc << 1) ^ POLY) & MASK if crc & (1 << 63) else (crc << 1) & MASK
        out.append(crc)
    return out


TABLE = _table()


def crc64(data: bytes) -> int:
    """CRC-64 (ECMA-182, MSB first, no reflection, initial value and final XOR 0)."""
    crc = 0
    for b in data:
        crc = TABLE[((crc >> 56) ^ b) & 0xFF] ^ ((crc << 8) & MASK)
    return crc


def read_reply(sock: socket.socket) -> dict:
    """The next message, unpacked by the 58-byte header, its CRC checked here."""

    def exact(n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = sock.recv(n - len(buf))
            assert chunk, "connection closed"
            buf += chunk
        return buf

    version, mtype, device, sec, frac, size, crc = HEADER.unpack(exact(HEADER.size))
    body = exact(size)
    assert crc64(body) == crc, "CRC-64 mismatch"
    content, metadata = body, {}
    if version == 2:
        ext, meta_head, meta_body, _ = struct.unpack(">HHII", body[:12])
        content = body[ext : len(body) - meta_head - meta_body]
        metadata = {"count": struct.unpack(">H", body[len(body) - meta_head - meta_body :][:2])[0]}
    return {
        "version": version,
        "type": mtype.rstrip(b"\0").decode(),
        "device": device.rstrip(b"\0").decode(),
        "timestamp": sec + frac / 2**32,
        "content": content,
        "metadata": metadata,
    }
