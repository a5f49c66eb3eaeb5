"""The command line: numbers it refuses before a run, and the same data for the same scenario and seed."""
from __future__ import annotations

import os
import select
import threading
from pathlib import Path

import numpy as np
import pytest
from sinsalign.protocol.axes import axis_map
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.protocol.kvh import KvhDecoder
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
    """A zero or negative duration, or --realtime with --speed, is refused before anything runs, the option named
    (not a fall-back to the scenario's length, a header-only log with exit 0, or one option silently winning)."""
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "argument" in err


def read_bytes(fd: int, stop: threading.Event, into: bytearray) -> None:
    """Everything written into the pty's other end, until ``stop`` and the line is drained."""
    while True:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if not ready:
            if stop.is_set():
                return
            continue
        try:
            into.extend(os.read(fd, 65536))
        except OSError:
            return


def bench_bytes(options: list[str]) -> bytes:
    """What ``sinsalign bench OPTIONS`` writes into a pty at ×50, read from its other end."""
    pty = PtyPair()
    raw = bytearray()
    stop = threading.Event()
    reader = threading.Thread(target=read_bytes, args=(pty.master_fd, stop, raw))
    reader.start()
    try:
        assert main(["bench", *options, "--port", pty.port_name, "--start-delay", "0", "--speed", "50"]) == 0
    finally:
        stop.set()
        reader.join()
        pty.close()
    return bytes(raw)


def test_bench_plays_the_data_sim_writes_for_the_same_seed(tmp_path: Path) -> None:
    """seed003 draws each IMU's bias signs per seed, and bench --seed draws them as sim --seed does: frames read back
    from a pty agree with sim's log of the same seed to the wire's resolution."""
    assert main(["sim", "seed003-20", "--seed", "2", "--duration", "0.5", "--out-dir", str(tmp_path)]) == 0
    t, dtheta, dv = (np.concatenate(c) for c in zip(*open_imu_log(tmp_path / "imu.csv").blocks(), strict=True))
    raw = bench_bytes(["--scenario", "seed003-20", "--seed", "2", "--duration", "0.5"])
    frames = [decode_imu(f) for f in FrameDecoder().feed(raw) if f.msg_type == MSG_IMU]
    assert len(frames) == len(t)
    np.testing.assert_allclose([f.t for f in frames], t, atol=1e-9)
    np.testing.assert_allclose([f.dtheta for f in frames], dtheta, rtol=0, atol=DTHETA_LSB_RAD)
    np.testing.assert_allclose([f.dv for f in frames], dv, rtol=0, atol=DV_LSB_MPS)


def test_bench_emulates_a_vendor_imu_with_the_axes_and_frame_of_its_configuration(tmp_path: Path) -> None:
    """bench --imu-format kvh1750 --config: the frames a KVH decoder reads back are the scenario's increments in the
    sensor's axes (x forward, y right, z down), to float32."""
    config = tmp_path / "kvh.toml"
    config.write_text('[imu]\naxes = ["y", "x", "-z"]\nrate_hz = 200.0\n')
    assert main(["sim", "seed000-swing", "--seed", "2", "--duration", "0.5", "--out-dir", str(tmp_path)]) == 0
    _, dtheta, dv = (np.concatenate(c) for c in zip(*open_imu_log(tmp_path / "imu.csv").blocks(), strict=True))
    raw = bench_bytes(["--scenario", "seed000-swing", "--seed", "2", "--duration", "0.5", "--imu-format", "kvh1750",
                       "--config", str(config)])
    got = KvhDecoder("1750", 200.0).feed(raw)
    C_b_s = axis_map(("y", "x", "-z")).T
    assert len(got.counter) == len(dtheta) and (np.diff(got.counter) % 128 == 1).all()
    np.testing.assert_allclose(got.dtheta, dtheta @ C_b_s.T, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(got.dv, dv @ C_b_s.T, rtol=1e-6, atol=1e-9)


def test_an_eval_table_is_stamped_with_its_command_and_commit(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    import subprocess
    argv = ["eval", "static", "--seeds", "1", "--no-fine", "--out-dir", str(tmp_path)]
    assert main(argv) == 0
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parents[2],
                          capture_output=True, text=True, check=True).stdout.strip()
    first = (tmp_path / "static.md").read_text().splitlines()[0]
    shown = " ".join([*argv[:-1], tmp_path.name])   # an absolute output folder by its name
    assert first.startswith(f"generated by `sinsalign {shown}` at commit {head}")
    assert first in capsys.readouterr().out
