"""The datasheet bank (service/align/datasheet_bank.py): which hypothesis about the datasheet it reports, and σ.

Each member here is a stand-in filter whose likelihood per update, attitude and σ the test sets; the filters
themselves are judged on simulated flights (tests/integration/test_gnss_aided.py, tests/accuracy/).
"""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG
from sinsalign.service.align.datasheet_bank import (
    CONFIRMED,
    HYPOTHESES,
    RULED_OUT_LOG,
    WIDER,
    DatasheetBank,
    scaled_grade,
)
from sinsalign.service.align.sensor_model import AttitudeSigma, SensorGrade

GRADE = SensorGrade(1e-6, 1e-5, 1e-3, 1e-4, 2e-4)


def rotation_about_up(angle_rad: float) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class StandIn:
    """A filter of ``grade`` whose update adds ``gain`` to its log likelihood; its heading is ``heading_rad`` and its
    σ ``sigma_deg`` (heading and level)."""

    def __init__(self, grade: SensorGrade) -> None:
        self.grade = grade
        self.log_likelihood = 0.0
        self.gain = 0.0
        self.heading_rad = 0.0
        self.sigma_deg = 0.1
        self.started_with: tuple[float, float] | None = None

    def start(self, C_b_n, C_b_b0, V_n, position, tilt_sigma_rad, heading_sigma_rad, velocity_sigma_mps, **options):
        self.started_with = (tilt_sigma_rad, heading_sigma_rad)

    def update(self, name: str, value: np.ndarray) -> bool:
        self.log_likelihood += self.gain
        return True

    def attitude(self, C_b_b0: np.ndarray, since_step_s: float = 0.0) -> np.ndarray:
        return rotation_about_up(self.heading_rad) @ C_b_b0

    @property
    def sigma(self) -> AttitudeSigma:
        return AttitudeSigma(self.sigma_deg, self.sigma_deg)

    def extra(self, name: str) -> np.ndarray:
        return np.array([self.heading_rad])

    @property
    def counters(self) -> dict:
        return {"fix": self.grade}


def bank_with(gains, headings_deg=(0.0, 0.0, 0.0, 0.0), sigmas_deg=(0.1, 0.3, 0.5, 1.0)) -> DatasheetBank:
    bank = DatasheetBank(StandIn, GRADE)
    for member, gain, heading, sigma in zip(bank.members, gains, headings_deg, sigmas_deg, strict=True):
        member.gain, member.heading_rad, member.sigma_deg = gain, heading * DEG, sigma
    bank.update("fix", np.zeros(3))
    return bank


def test_each_hypothesis_scales_the_datasheet_s_biases_and_noise():
    bank = DatasheetBank(StandIn, GRADE)
    for (bias, noise), member in zip(HYPOTHESES, bank.members, strict=True):
        assert member.grade == scaled_grade(GRADE, (bias, noise))
        assert member.grade.gyro_bias_rad_s == pytest.approx(bias * GRADE.gyro_bias_rad_s)
        assert member.grade.acc_vrw_ms_rts == pytest.approx(noise * GRADE.acc_vrw_ms_rts)
        assert member.grade.base_motion_m_rts == GRADE.base_motion_m_rts


def test_every_hypothesis_starts_from_the_coarse_stage_s_attitude_and_sigma():
    """The same σ: a looser start would weigh the looser hypotheses at the hand-over (σ 0.07° jumped to 4° for 3 s)."""
    bank = DatasheetBank(StandIn, GRADE)
    bank.start(np.eye(3), np.eye(3), np.zeros(3), np.zeros(3), 0.001, 0.01, 0.1)
    assert [m.started_with for m in bank.members] == [(0.001, 0.01)] * 4


def test_data_that_favour_the_datasheet_leave_its_filter_s_attitude_and_sigma():
    bank = bank_with((0.0, -20.0, -30.0, -40.0), headings_deg=(0.0, 1.0, 2.0, 3.0))
    assert bank.believed == 0
    sigma = bank.sigma_about(np.eye(3))
    assert sigma.heading_deg == pytest.approx(0.1, rel=1e-6)
    assert np.allclose(bank.attitude(np.eye(3)), np.eye(3))


def test_until_the_data_tell_them_apart_sigma_holds_the_looser_hypotheses():
    """Equal likelihoods: the datasheet's attitude, σ the mixture's (their σ and their distance from it)."""
    bank = bank_with((0.0, 0.0, 0.0, 0.0), headings_deg=(0.0, 0.4, 0.0, 0.0))
    assert bank.believed == 0
    expected = np.sqrt(0.25 * (0.1**2 + (0.3**2 + 0.4**2) + 0.5**2 + 1.0**2))
    assert bank.sigma_about(np.eye(3)).heading_deg == pytest.approx(expected, rel=1e-6)
    assert bank.weights() == pytest.approx([0.25] * 4)


def test_a_datasheet_the_data_rule_out_gives_way_to_the_loosest_hypothesis_not_ruled_out():
    # the tenfold hypothesis fits best; the hundredfold-bias one is within e^-10 of it, the last one is not
    bank = bank_with((0.0, 30.0, 30.0 - RULED_OUT_LOG + 1.0, 30.0 - RULED_OUT_LOG - 1.0),
                     headings_deg=(1.0, 0.2, 0.1, 0.0))
    assert bank.believed == 2
    assert bank.filter is bank.members[2]
    assert np.allclose(bank.attitude(np.eye(3)), rotation_about_up(0.1 * DEG))
    assert bank.sigma_about(np.eye(3)).heading_deg >= 0.5   # never below the reported filter's own


def test_the_datasheet_is_confirmed_once_the_hypotheses_that_would_change_its_sigma_hold_under_one_percent():
    """The tenfold hypothesis, its σ over twice the datasheet's, at 2 % of the weight: not confirmed; at 0.5 %:
    confirmed. The same weights on hypotheses whose σ is within twice the datasheet's change nothing."""
    lead = np.log(0.98 / 0.02)
    assert 1.0 - CONFIRMED < 0.02
    wide = bank_with((lead, 0.0, -np.inf, -np.inf), sigmas_deg=(0.1, 0.1 * WIDER * 1.1, 0.5, 1.0))
    assert wide.weights()[1] == pytest.approx(0.02) and not wide.sigma_about(np.eye(3)).confirmed
    wide = bank_with((np.log(0.995 / 0.005), 0.0, -np.inf, -np.inf), sigmas_deg=(0.1, 0.1 * WIDER * 1.1, 0.5, 1.0))
    assert wide.sigma_about(np.eye(3)).confirmed
    alike = bank_with((lead, 0.0, -np.inf, -np.inf), sigmas_deg=(0.1, 0.1 * WIDER * 0.9, 0.5, 1.0))
    assert alike.sigma_about(np.eye(3)).confirmed
    far = bank_with((lead, 0.0, -np.inf, -np.inf), headings_deg=(0.0, 0.3, 0.0, 0.0),
                    sigmas_deg=(0.1, 0.1, 0.5, 1.0))   # the same σ, but 3σ away from the datasheet's attitude
    assert not far.sigma_about(np.eye(3)).confirmed


def test_a_looser_hypothesis_reported_is_confirmed_by_its_own_sigma():
    bank = bank_with((0.0, 30.0, 29.0, -np.inf), headings_deg=(1.0, 0.2, 0.1, 0.0))
    assert bank.believed == 2 and bank.sigma_about(np.eye(3)).confirmed


def test_the_weights_are_the_likelihoods_normalised():
    bank = bank_with((0.0, np.log(3.0), -np.inf, 0.0))
    assert bank.weights() == pytest.approx([0.2, 0.6, 0.0, 0.2])


def test_the_modes_read_the_reported_filter_s_states_and_the_datasheet_filter_s_counts():
    """A mode's reads of the filter's own states (a transfer's mounting, an odometer's scale factor) come from the
    filter it reports; the gate's counts from the datasheet's (a looser filter's would jump when it is reported)."""
    bank = bank_with((0.0, 30.0, 30.0 - RULED_OUT_LOG + 1.0, 30.0 - RULED_OUT_LOG - 1.0),
                     headings_deg=(1.0, 0.2, 0.1, 0.0))
    assert bank.extra("odo") == pytest.approx([0.1 * DEG])
    assert bank.counters == {"fix": GRADE}
