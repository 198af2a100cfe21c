import numpy as np
import pytest

from uwbwb.models.imu import GRADES, ImuConvention, ImuErrorModel
from uwbwb.models.ins import GRAVITY_MPS2
from uwbwb.types import ImuLog


def _log(acc, gyro):
    return ImuLog(np.arange(len(acc)) * 0.01, np.atleast_2d(acc), np.atleast_2d(gyro))


def test_units_g_and_deg_per_s_are_converted():
    raw = _log([[0.0, 0.0, 1.0]], [[0.0, 0.0, 90.0]])
    body = ImuConvention(acc_unit="g", gyro_unit="deg/s").to_body(raw)
    np.testing.assert_allclose(body.acc_mps2[0], [0, 0, GRAVITY_MPS2])
    np.testing.assert_allclose(body.gyro_radps[0], [0, 0, np.pi / 2])
    same = ImuConvention().to_body(raw, check=False)
    np.testing.assert_allclose(same.acc_mps2, raw.acc_mps2)


def test_sensor_to_body_rotation_and_scale():
    # a z-down sensor (x fwd, y right) in a z-up body: level and at rest it reads -g on z
    conv = ImuConvention(R_body_sensor=np.diag([1.0, -1.0, -1.0]), acc_scale=GRAVITY_MPS2 / 10.36)
    body = conv.to_body(_log([[0.0, 0.0, -10.36]], [[0.0, 0.1, -0.2]]))
    np.testing.assert_allclose(body.acc_mps2[0], [0, 0, GRAVITY_MPS2])
    np.testing.assert_allclose(body.gyro_radps[0], [0, -0.1, 0.2])


@pytest.mark.parametrize("R", [np.diag([1.0, 1.0, -1.0]), np.ones((3, 3)), np.eye(2)])
def test_improper_or_invalid_rotation_is_rejected(R):
    with pytest.raises(ValueError, match="proper rotation"):
        ImuConvention(R_body_sensor=R)


def test_bad_units_and_lever_arm_are_rejected():
    with pytest.raises(ValueError, match="acc_unit"):
        ImuConvention(acc_unit="mg")
    with pytest.raises(ValueError, match="gyro_unit"):
        ImuConvention(gyro_unit="dps")
    with pytest.raises(ValueError, match="lever_arm"):
        ImuConvention(lever_arm_m=[0.1, 0.2])
    with pytest.raises(ValueError, match="deg/s"):
        ImuErrorModel(gyro_bias_sigma_radps=1.0)


def test_error_model_statistics(rng):
    model = ImuErrorModel(acc_noise_density=2e-3, gyro_noise_density=1e-4, acc_bias_sigma_mps2=0.0,
                          gyro_bias_sigma_radps=0.0, acc_bias_rw=0.0, gyro_bias_rw=0.0)
    t = np.arange(100_000) * 0.01
    out = model.sample(t, np.zeros((t.size, 3)), np.zeros((t.size, 3)), rng=rng)
    np.testing.assert_allclose(out.imu.acc_mps2.std(0), 2e-3 * 10, rtol=0.02)
    np.testing.assert_allclose(out.imu.gyro_radps.std(0), 1e-4 * 10, rtol=0.02)
    # bias random walk: variance grows as density² · t
    rw = ImuErrorModel(acc_bias_sigma_mps2=0.0, gyro_bias_sigma_radps=0.0, acc_bias_rw=1e-3, gyro_bias_rw=0.0)
    finals = []
    for _ in range(400):
        finals.append(rw.sample(t[:1001], np.zeros((1001, 3)), np.zeros((1001, 3)), rng=rng).acc_bias_mps2[-1])
    np.testing.assert_allclose(np.std(finals), 1e-3 * np.sqrt(10.0), rtol=0.1)


def test_same_seed_same_numbers():
    t = np.arange(100) * 0.01
    a = GRADES["consumer"].sample(t, np.zeros((100, 3)), np.zeros((100, 3)), rng=np.random.default_rng(3))
    b = GRADES["consumer"].sample(t, np.zeros((100, 3)), np.zeros((100, 3)), rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a.imu.acc_mps2, b.imu.acc_mps2)


def test_grades_are_ordered_and_scaling_works():
    c, i, t = GRADES["consumer"], GRADES["industrial"], GRADES["tactical"]
    assert c.gyro_bias_sigma_radps > i.gyro_bias_sigma_radps > t.gyro_bias_sigma_radps
    assert c.scaled(2.0).acc_noise_density == 2 * c.acc_noise_density
    assert c.scaled(2.0).mag_heading_sigma_rad == c.mag_heading_sigma_rad
