"""Bad input fails loudly at the public boundary, with a message naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import BeamSweep, ProcessingConfig, RadarConfig, RisPose, delay_doppler_map, scan_beams, self_localize
from risloc_rt.model.beat import add_noise
from risloc_rt.model.paths import PathSet
from risloc_rt.model.simulate import simulate

RADAR = RadarConfig(num_samples=64, num_chirps=16)
PROCESSING = ProcessingConfig(n_dft=2 * 64 - 1, k_dft=4 * 16)  # N_DFT = 2N - 1, K_DFT = 4K
M = 3
SWEEP = BeamSweep(np.zeros((M, 2)))


def good_cube() -> np.ndarray:
    return np.ones((M, RADAR.num_chirps, RADAR.num_samples), complex)


# ------------------------------------------------------------------------------ cubes
@pytest.mark.parametrize("cube, message", [
    pytest.param(np.ones((16, 64), complex), r"cube has shape \[16, 64\], expected \[\*, \*, \*\]", id="2-D"),
    pytest.param(np.ones((M, 15, 64), complex), r"K=16 chirps and N=64 samples", id="wrong-K"),
    pytest.param(np.ones((M, 16, 65), complex), r"K=16 chirps and N=64 samples", id="wrong-N"),
    pytest.param(np.ones((M, 64, 16), complex), r"axis order is \(beams, chirps, samples\)", id="transposed"),
    pytest.param(np.ones((0, 16, 64), complex), r"cube is empty", id="empty"),
    pytest.param(np.ones((M + 1, 16, 64), complex), r"cube has 4 beams .* sweep has 3 angles", id="beams!=angles"),
])
def test_bad_cube_shapes(cube, message):
    with pytest.raises(ValueError, match=message):
        scan_beams(cube, SWEEP, RADAR, PROCESSING)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, complex(0, np.nan)])
def test_non_finite_cube(bad):
    cube = good_cube()
    cube[1, 7, 3] = bad
    with pytest.raises(ValueError, match=r"cube contains 1 NaN or infinite value"):
        scan_beams(cube, SWEEP, RADAR, PROCESSING)
    with pytest.raises(ValueError, match=r"frame contains 1 NaN or infinite value"):
        delay_doppler_map(cube[1], RADAR, PROCESSING)


def test_frame_must_be_2d_and_match_the_radar():
    with pytest.raises(ValueError, match=r"frame has shape \[3, 16, 64\], expected \[\*, \*\]"):
        delay_doppler_map(good_cube(), RADAR, PROCESSING)
    with pytest.raises(ValueError, match=r"K=16 chirps and N=64 samples"):
        delay_doppler_map(np.ones((64, 16), complex), RADAR, PROCESSING)


def test_sweep_with_fewer_angles_than_frames():
    with pytest.raises(ValueError, match=r"cube has 3 beams \(frames\) but the sweep has 2 angles"):
        scan_beams(good_cube(), BeamSweep(np.zeros((2, 2))), RADAR, PROCESSING)


def test_sweep_must_be_a_beam_sweep():
    with pytest.raises(TypeError, match="sweep must be a BeamSweep"):
        scan_beams(good_cube(), np.zeros((M, 2)), RADAR, PROCESSING)


def test_empty_arrays_are_rejected():
    with pytest.raises(ValueError, match=r"angles is empty"):
        BeamSweep(np.zeros((0, 2)))
    with pytest.raises(ValueError, match=r"angles has shape \[3\], expected \[\*, 2\]"):
        BeamSweep(np.zeros(3))


# ------------------------------------------------------------------------------ configs
@pytest.mark.parametrize("field", ["bandwidth", "chirp_duration", "carrier_frequency", "sample_rate"])
@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf])
def test_radar_rejects_non_positive_or_non_finite(field, value):
    with pytest.raises(ValueError, match=rf"{field}=.* must be a finite number > 0"):
        RadarConfig(**{field: value})


@pytest.mark.parametrize("field", ["num_samples", "num_chirps"])
def test_radar_counts_must_be_positive_integers(field):
    with pytest.raises(ValueError, match=rf"{field}=0 must be an integer >= 1"):
        RadarConfig(**{field: 0})
    with pytest.raises(TypeError, match=rf"{field}=12.5 must be an integer"):
        RadarConfig(**{field: 12.5})


def test_bandwidth_above_carrier_is_rejected():
    with pytest.raises(ValueError, match="bandwidth=.* must be smaller than carrier_frequency"):
        RadarConfig(bandwidth=70e9)


@pytest.mark.parametrize("n_dft, k_dft, message", [
    (63, 64, r"n_dft=63 is smaller than the number of ADC samples N=64"),
    (127, 15, r"k_dft=15 is smaller than the number of chirps K=16"),
])
def test_dft_shorter_than_the_data(n_dft, k_dft, message, make_scenario):
    processing = ProcessingConfig(n_dft=n_dft, k_dft=k_dft)
    with pytest.raises(ValueError, match=message):
        scan_beams(good_cube(), SWEEP, RADAR, processing)
    with pytest.raises(ValueError, match=message):
        delay_doppler_map(good_cube()[0], RADAR, processing)
    with pytest.raises(ValueError, match=message):
        make_scenario(radar=RADAR, processing=processing)


def test_unknown_window():
    with pytest.raises(ValueError, match=r"window='hanning-typo' is not a window scipy.signal.get_window knows"):
        ProcessingConfig(window="hanning-typo")


def test_processing_enumerations_and_ranges(make_processing):
    with pytest.raises(ValueError, match=r"doppler_search='fast' must be 'zoom' or 'full'"):
        ProcessingConfig(doppler_search="fast")
    with pytest.raises(ValueError, match=r"delta=-1e-09 must be a finite number >= 0"):
        ProcessingConfig(delta=-1e-9)
    with pytest.raises(ValueError, match=r"min_range=100.0 m excludes every delay bin"):
        scan_beams(good_cube(), SWEEP, RADAR, make_processing(RADAR, min_range=100.0))


# ------------------------------------------------------------------------------ randomness
@pytest.mark.parametrize("rng", [np.random.RandomState(0), 0, None, np.random.default_rng(0).bit_generator])
def test_rng_must_be_a_generator(rng, make_scenario):
    scenario = make_scenario(radar=RADAR)
    with pytest.raises(TypeError, match="rng must be a numpy.random.Generator"):
        simulate(scenario, rng=rng)
    with pytest.raises(TypeError, match="rng must be a numpy.random.Generator"):
        add_noise(good_cube(), 1.0, rng)


# ------------------------------------------------------------------------------ geometry and angles
def test_pose_up_parallel_to_normal():
    with pytest.raises(ValueError, match=r"up=.* is parallel to normal="):
        RisPose(position=np.zeros(3), normal=np.array([0.0, 0.0, 2.0]), up=np.array([0.0, 0.0, -1.0]))
    with pytest.raises(ValueError, match=r"is parallel to normal"):
        RisPose.facing([0.0, 0.0, 5.0], [0.0, 0.0, 0.0])  # looking straight down with world up
    with pytest.raises(ValueError, match=r"normal=\[0.0, 0.0, 0.0\] must be a non-zero vector"):
        RisPose(position=np.zeros(3), normal=np.zeros(3))
    with pytest.raises(ValueError, match="target coincides with position"):
        RisPose.facing([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])


def test_azimuth_grid_step_must_divide_the_span():
    with pytest.raises(ValueError, match=r"\(stop - start\)/step = 6.* is not a whole number"):
        BeamSweep.azimuth_grid(*np.deg2rad([-45.0, 45.0, 14.0]))
    with pytest.raises(ValueError, match=r"stop=.* must be >= start="):
        BeamSweep.azimuth_grid(0.5, -0.5, 0.1)
    with pytest.raises(ValueError, match=r"step=0.0 must be a finite number > 0"):
        BeamSweep.azimuth_grid(-0.5, 0.5, 0.0)


@pytest.mark.parametrize("angles", [[[30.0, 0.0]], [[0.0, 10.0]], [[-45.0, 0.0], [45.0, 0.0]]])
def test_angles_in_degrees_are_rejected(angles):
    with pytest.raises(ValueError, match=r"within ±π/2 rad .* Angles are in radians"):
        BeamSweep(np.array(angles))


def test_azimuth_grid_in_degrees_is_rejected():
    with pytest.raises(ValueError, match="Angles are in radians"):
        BeamSweep.azimuth_grid(-45.0, 45.0, 1.5)


def test_ue_behind_the_panel_is_rejected(make_scenario):
    with pytest.raises(ValueError, match=r"behind the RIS panel"):
        make_scenario(ris_facing=(0.0, 30.0, 0.0))  # the panel faces away from the UE


# ------------------------------------------------------------------------------ paths and localize
def test_path_set_validation(tone_paths):
    with pytest.raises(ValueError, match=r"delay contains negative values"):
        tone_paths(1.0, -1e-9, 0.0)
    with pytest.raises(ValueError, match=r"labels has 0 entries, expected 1"):
        PathSet(np.ones(1, complex), np.ones(1), np.zeros(1), np.full((1, 2), np.nan), np.full((1, 2), np.nan), ())
    with pytest.raises(ValueError, match=r"must be NaN on the same paths"):
        PathSet(np.ones(1, complex), np.ones(1), np.zeros(1), np.zeros((1, 2)), np.full((1, 2), np.nan), ("x",))
    with pytest.raises(ValueError, match=r"delay has shape \[2\], expected \[1\]"):
        PathSet(np.ones(1, complex), np.ones(2), np.zeros(1), np.zeros((1, 2)), np.zeros((1, 2)), ("x",))


def test_self_localize_argument_types():
    pose = RisPose(np.zeros(3), np.array([0.0, 1.0, 0.0]))
    with pytest.raises(ValueError, match=r"loopback_delay=-1e-09 must be a finite number >= 0"):
        self_localize(good_cube(), sweep=SWEEP, radar=RADAR, processing=PROCESSING, pose=pose, loopback_delay=-1e-9)
    with pytest.raises(TypeError, match="pose must be a RisPose"):
        self_localize(good_cube(), sweep=SWEEP, radar=RADAR, processing=PROCESSING, pose=np.zeros(3),
                      loopback_delay=0.0)


@pytest.mark.parametrize("scale", [1e-200, 1e-160, 1.0, 1e150, 1e200])
def test_a_finite_cube_of_any_magnitude_passes_the_check_and_a_bad_value_in_it_does_not(scale):
    # check_beat_cube's one-pass test (the sum of squares finite and positive) overflows beyond ~1e154 and
    # underflows below ~1e-162: there the exact checks decide, so every magnitude gives the same answers
    from dsp.detection import check_beat_cube

    cube = scale * (np.random.default_rng(1).standard_normal((M, 16, 64)) + 1j)
    np.testing.assert_array_equal(check_beat_cube(cube, RADAR), cube)
    np.testing.assert_array_equal(check_beat_cube(cube[:, :, ::-1], RADAR), cube[:, :, ::-1])  # not contiguous
    for bad in (np.nan, np.inf, complex(0, -np.inf)):
        spoiled = cube.copy()
        spoiled[2, 15, 63] = bad
        with pytest.raises(ValueError, match=r"cube contains 1 NaN or infinite value"):
            check_beat_cube(spoiled, RADAR)
    with pytest.raises(ValueError, match=r"cube is all zeros"):
        check_beat_cube(0.0 * cube, RADAR)
    one = np.zeros_like(cube)
    one[0, 0, 0] = scale  # a single non-zero sample is not all zeros, however small or large
    np.testing.assert_array_equal(check_beat_cube(one, RADAR), one)
