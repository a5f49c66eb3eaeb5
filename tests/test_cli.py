"""The command line: numbers it refuses before a run, and the same data for the same scenario and seed."""
from __future__ import annotations

import os
import select
import threading
from pathlib import Path

import numpy as np
import pytest
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.protocol.serial_frame import DTHETA_LSB_RAD, DV_LSB_MPS, MSG_IMU, FrameDecoder, decode_imu
from sinsalign.tools.virtual_imu import PtyPair

from sinsalign.cli import main


@pytest.mark.parametrize(("argv", "message"), [
    (["sim", "static", "--duration", "0"], "0 must be above 0"),
    (["sim", "static", "--duration", "-5"], "-5 must be above 0"),
    (["sim", "static", "--seed", "-1"], "-1 must be at least 0"),
    (["bench", "--speed", "0"], "0 must be above 0"),
    (["bench", "--aid-late", "-0.1"], "-0.1 must be at least 0"),
    (["demo", "--duration", "nan"], "nan must be above 0"),
    (["demo", "--speed", "2", "--realtime"], "not allowed with argument"),
    (["eval", "static", "--seeds", "0"], "0 must be at least 1"),
    (["eval", "static", "--seeds", "2.5"], "'2.5' is not an integer"),
    (["watch", "--duration", "inf"], "inf must be above 0"),
    (["benchmark", "--stream-hours", "-1"], "-1 must be at least 0"),
    (["soak", "--report-every", "0"], "0 must be above 0"),
])
def test_a_number_out_of_range_is_a_usage_error(capsys: pytest.CaptureFixture[str], argv: list[str],
                                               message: str) -> None:
    """A zero or negative duration used to fall back to the scenario's length or write a header-only log with exit 0;
    --realtime silently overrode --speed. Now each is refused before anything runs, the option named."""
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "argument" in err


def read_imu_frames(fd: int, stop: threading.Event, into: list) -> None:
    """Decode IMU frames from a pty's master side until ``stop`` and no more bytes."""
    decoder = FrameDecoder()
    while True:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if not ready:
            if stop.is_set():
                return
            continue
        try:
            data = os.read(fd, 65536)
        except OSError:
            return
        into.extend(decode_imu(f) for f in decoder.feed(data) if f.msg_type == MSG_IMU)


def test_bench_plays_the_data_sim_writes_for_the_same_seed(tmp_path: Path) -> None:
    """seed003 draws each IMU's bias signs per seed: bench --seed used to skip the draw, so its "seed 2" was other
    data than sim --seed 2's. Frames read back from a pty agree with sim's log to the wire's resolution."""
    assert main(["sim", "seed003-20", "--seed", "2", "--duration", "0.5", "--out-dir", str(tmp_path)]) == 0
    t, dtheta, dv = (np.concatenate(c) for c in zip(*open_imu_log(tmp_path / "imu.csv").blocks(), strict=True))
    pty = PtyPair()
    frames: list = []
    stop = threading.Event()
    reader = threading.Thread(target=read_imu_frames, args=(pty.master_fd, stop, frames))
    reader.start()
    try:
        assert main(["bench", "--scenario", "seed003-20", "--seed", "2", "--duration", "0.5", "--port",
                     pty.port_name, "--start-delay", "0", "--speed", "50"]) == 0
    finally:
        stop.set()
        reader.join()
        pty.close()
    assert len(frames) == len(t)
    np.testing.assert_allclose([f.t for f in frames], t, atol=1e-9)
    np.testing.assert_allclose([f.dtheta for f in frames], dtheta, rtol=0, atol=DTHETA_LSB_RAD)
    np.testing.assert_allclose([f.dv for f in frames], dv, rtol=0, atol=DV_LSB_MPS)
