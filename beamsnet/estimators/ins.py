"""INS/DVL error-state Kalman filter: strapdown mechanisation at the IMU rate, corrected by
each bottom-track DVL beam (or each axis of the DVL's own velocity) as a scalar
measurement (issue 11, item 1; fit for a real vehicle in issue 24, item 3).

Entry points: ``run_arrays`` (arrays in, no dataset: IMU times and samples, DVL times and
beams or velocity, lever arms, mounting, the place, a ``Start`` and the ``Instrument``'s
noise), ``run_mission`` (a thin adapter: a simulated, imported-with-IMU or recorded
mission's streams and attributes into ``run_arrays``), ``InsDvlFilter`` (the estimator
of the tables). Settings: ``FilterConfig`` (``load_config`` reads one from TOML,
``beamsnet estimate/evaluate --filter-config``). Output: ``FilterTrack`` at every ping,
with the position and its std, the DVL's velocity in the DVL frame as the filter has it
(with the beam states, the nominal mounting turned by the estimated misalignment mu:
a + a x mu, its covariance with mu's; in the nominal frame a misaligned DVL's velocity
is off by the speed times the misalignment), the attitude, the instrument states,
``accepted`` (a
measurement of the ping was used), ``availability`` (their share) and ``events``;
``at_pings`` reads any of its fields at the samples of a beamsnet ``Windows``.

Conventions are auvsim's (NED world, FRD body, body -> NED rotation C, SI units). The
mechanised point is the IMU; the DVL and the body origin (the reference point) are
reached through the lever arms. The streams keep their own clocks: a ping is applied at
the IMU sample nearest its time (at or before it, it would lag by half a sample on
average: 5 ms at 100 Hz, a quarter of how well check-log knows a DVL's clock); nothing is
resampled.

Mechanisation (Groves 2013, "Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems", 2nd ed., sec. 5.4, first-order form in a local-level frame), from
IMU sample i - 1 to i, dt_i = t_i - t_{i-1}::

    v_i = v_{i-1} + dt (C_{i-1} f_{i-1} + g(p_{i-1}) - 2 Omega_ie x v_{i-1})
    p_i = p_{i-1} + dt v_i
    C_i = C_{i-1} Exp(dt (w_i - C'_i^T Omega_ie)),   C'_i = C_{i-1} Exp(dt w_i)

with f and w the bias-corrected samples, g(p) = (0, 0, g + g' p_down) and Omega_ie the
Earth's rate in NED. Whenever the latitude is known (a recorded log always; a simulated
mission with a geographic origin, whose attributes carry ``latitude_deg``), Omega_ie and
g are the WGS-84 Earth rate and normal gravity at the frame's origin, and g' the normal
gravity's free-air growth with depth, 3.1e-6 m/s^2 per m (``auvsim.physics.earth``;
under water the true growth is less by the water above, 4 pi G rho = 0.9e-6, but the
free-air term is what auvsim's IMU reads, and over the tens of metres a mission changes
depth the difference stays under 1e-5 m/s^2); without one, auvsim's flat world that does
not rotate (Omega_ie = 0, g' = 0, the mission's own g). The
transport rate (the local-level frame turning as the vehicle moves over the curved Earth,
v / R: 3e-7 rad/s at 2 m/s, 2 % of the Earth's rate) and the change of gravity with the
distance travelled are left out: over the few kilometres of a mission the frame turns
by under 0.03 deg and the position error they make stays under a few centimetres, far
below the DVL's. This is the discrete form auvsim's truth obeys: MuJoCo's semi-implicit
Euler step holds the acceleration recorded at step i - 1 over the step and rotates by
the angular velocity recorded at step i, and the simulated accelerometer reads C^T (a +
2 Omega_ie x v - g(p)) and the gyro w + C^T Omega_ie at the same step. The Earth's rate is
taken at the sample's own attitude, C'_i (to O(dt Omega_ie)), as the gyros read it: at
C_{i-1} instead, a turn at rate r tilted the solution by dt r Omega_ie per second
(1.6e-7 rad/s at 15 deg/s and 100 Hz, 1.1 m north after 240 s of a noise-free
turning circle), and the surface's gravity at 20 m depth put 6e-5 m/s^2 into the
vertical (1.8 m down). So noise-free data integrate back exactly at the body origin (to
a few parts in a million on the rotating Earth); at the IMU point (and the DVL) the one
discretisation error is the lever arm's (derived, and tested to 1e-9, in
``tests/test_ins.py::lever_arm_error``).

A real IMU's sample is another thing: the specific force over the interval that ends at
its time (an average, or an increment over the interval's length), not a value held from
its time on. For a recorded log (and by default for arrays: ``run_arrays``'
``imu_samples``) the step from i - 1 to i therefore takes sample i, turned by the
attitude at the interval's middle, and moves the position by the mean of the old and new
velocity (Groves eqs. 5.36-5.38)::

    v_i = v_{i-1} + dt (C_{i-1} Exp(dt w_nb,i / 2) f_i + g(p_{i-1}) - 2 Omega_ie x v_{i-1})
    p_i = p_{i-1} + dt (v_{i-1} + v_i) / 2

with w_nb = w - C^T Omega_ie. The held form on such samples turns the specific force half
a sample late (dt r / 2 in a turn at rate r): an ideal turning circle sampled so drifts
0.10 m from its known answer in 60 s, against 0.01 mm (``tests/test_ins_real.py``). On
the Snapir's six segments, which say nothing of their IMU's sampling, the mid-interval
form lowers the rms of the DVL innovations on every one (by 0.02 to 0.32 mm/s; pooled
4.86 against 4.98 mm/s): the data agree with it, whatever the reference says. Savage's
coning and sculling terms beyond that are below the logs' rounding at 100 Hz.

Error state (x = x_hat + dx; Groves ch. 14.2, Sola 2017 "Quaternion kinematics for the
error-state Kalman filter" sec. 7 for the global attitude error): dp, dv (NED, m, m/s),
attitude error theta with C = Exp(theta) C_hat (NED, rad), accelerometer and gyro bias
errors (body, m/s^2, rad/s), and with ``beam_states`` (on for recorded logs and arrays)
14 instrument states: each measurement's scale factor s_k and bias c_k (4 + 4: per beam,
or per DVL axis), the DVL frame's misalignment mu (3, rad) and the DVL's lever-arm error
(3, m); with ``slow_error_states`` (on where beams are measured and the DVL has a slow
error) 3 more, the DVL's slow velocity error e in its frame, which every beam sees along
its direction (the c_k are then constant); and with ``gyro_matrix_states`` (on where the
IMU states the spreads: a
simulated file's ``-full`` grades) 9 more, the gyros' scale factors and misalignments,
K_g in measured w = (I + K_g) w + b_g + n_g (Groves sec. 4.4.6's gyro error model,
auvsim's simulated IMU), used as w = (I - K_g)(w_measured - b_g) to first order.
Continuous error dynamics (Groves eq. 14.64 without the curvature terms, with K_g's)::

    dp' = dv,   dv' = -[C f x] theta - C db_a - 2 Omega_ie x dv + g' dp_d e_d - C n_a,
    theta' = -Omega_ie x theta - C db_g - C dK_g w - C n_g,
    db_a' = w_ba,  db_g' = w_bg  (random walks),  c_k' = -c_k / tau + w_c (``bias_time``;
    constant without; with the slow-error states e' = -e / tau + w_e and c_k constant),
    s, mu, L, K_g constant

propagated at every IMU sample with Phi = I + F dt and Q = diag(...) dt (Groves eq.
14.72-14.82, first order), applied to the sparse blocks only. Measurement k, along the
unit direction d_k of the DVL frame (a beam, or an axis of its velocity)::

    y_k = (1 + s_k) (d_k + mu x d_k) . M^T (C^T v + w x L) + c_k (+ d_k . e) + n_k

with M the nominal mounting (DVL frame -> body) and L = r_dvl - r_imu: one scalar update
each (Groves sec. 3.2.5, sequential processing of uncorrelated measurements), so one to
four beams all help. n_k is white with the instrument's std (a simulated instrument's grows
with the speed, as its beams' noise does: ``noise_speed_coeff`` times the DVL point's
predicted speed at the ping, per beam or through the Janus geometry per axis), plus what
the ping's timing uncertainty (``clock_stds`` on a recorded log, 0 for simulated clocks)
makes of the rate at which y_k changes. Each innovation is gated by chi-square with 1 dof at
``gate_probability``. A beam is used where it has bottom lock (``dvl/valid``) on a ping
not in water track (``dvl/mode`` != 1).

No silent divergence: the watch counts, over the last ``watch_pings`` pings, the
measurements the gate rejected; when they reach ``watch_share`` of those offered (and the
current ping had one), the velocity is restarted from the measurements (its variance set
to cover the worst innovation, its correlations dropped), the attitude's variance gets
its initial prior back and the position's grows by what that velocity error moves it
over the window. Each restart is an ``Event`` of the track (ping, time, one line), listed
by ``beamsnet estimate``. A wrong state makes every beam disagree with it while the beams
agree among themselves; an outlier makes one beam disagree with the others. So where a
ping has four beams, its rejections count only if the beams pass the parity check: with
a the unit vector of a^T D = 0 (D the beams' directions; the combination the Janus error
velocity is made of, in which a common velocity, misalignment or timing error cancels)
and z_k = (y_k - c_k) / (1 + s_k), (a . z)^2 <= gate sum_k a_k^2 (r_k + P_ck). Three
beams, or a DVL's velocity, have no redundancy, and every rejection counts.

Adaptive measurement noise (``adaptive = "innovation"``, the estimator ``INS/DVL
(adaptive)``): the model-based adaptive baseline, innovation-based adaptive estimation
(IAE) after Mohamed & Schwarz 1999, "Adaptive Kalman filtering for INS/GPS", Journal of
Geodesy 73, 193-203 (their IAE): the innovations' covariance estimated over a sliding window
of N of them, C_v = (1/N) sum_j v_j v_j^T, and the measurement noise R = C_v - H P^- H^T.
Here R keeps the stated shape (the beams' equal noise, or a velocity's Janus axes) and
its size is estimated, R = lambda R_stated, from the last N scalar innovations nu_j of
the DVL's measurements (each with its predicted h_j P_j h_j^T, what the ping's earlier
measurements left, and the timing term t_j)::

    lambda = (1/N) sum_j (min(nu_j^2, gate S_j) / kappa - h_j P_j h_j^T - t_j) / r_j

with r_j the stated variance of measurement j, S_j its innovation variance and kappa =
0.998 what winsorising at the gate keeps of a normal's variance (an outlier moves lambda
by at most gate S / (N r), and a filter told too little noise, whose gate rejects good
measurements, still sees them). lambda is used from the next ping on, once
``ADAPTIVE_START`` innovations are in (the window then grows to N), clipped to the squares
of ``adaptive_range`` (0.5 to 10 times the stated std), so R stays diagonal with every
variance at least a quarter of the stated one: positive definite by construction. One
lambda for the four beams, not one each: with sequential scalar updates a beam's
innovation is what the ping's earlier beams left, and per-beam windows drifted apart
(on a 120 s zigzag whose beams were 3x noisier than stated, three beams fell to the
floor and the last took the noise; pooled, lambda came within 6 % of 9, and within
3 % over 200 s). Only R is adapted: the DVL's noise is what changes with the bottom,
the altitude and the water, and the innovations see it directly, while Q's IMU
densities come from the instrument's datasheet and the quantisation (Mohamed & Schwarz
adapt Q through K C_v K^T, which moves every state's noise at once from the same few
innovations). The filter stays the Kalman filter above: every measurement is gated
against its innovation variance with the adapted R and counted, and the divergence
watch is unchanged (its restart still uses the stated noise). With ``adaptive =
"none"`` the loop does the fixed filter's arithmetic exactly: its outputs are
bit-identical to the filter's before the setting existed.

Learned DVL noise (``adaptive = "learned"``, the estimator ``INS/DVL (learned noise)``):
at every ping the loop records six features of the IMU since the previous ping and of
the ping's innovations and runs a small network (``beamsnet.estimators.noisemodel``, its
arrays handed to the loop) whose bounded output scales the DVL's white variances and the
drive of the bias states c_k from the next ping on; ``beamsnet.estimators.noisenet``
gives the reasons, the loss and the training. The track records what the training reads
(``features``, ``innovation``, ``innovation_hph``, ``noise_scale``). The
fixed filter's arithmetic does not change.

Noise from the instrument: the IMU's densities, bias spreads and Gauss-Markov drives from
the mission's attributes (a simulated file's turn-on spread from its config, where the
attributes hold the drawn value), with a recorded log's rounding added
(``quantisation_density``); the beams' white noise from ``dvl_noise_std`` (which the
import measures on the logged error velocity where the log states none:
``auvsim.data.beams.beam_noise_from_error_velocity``), a velocity's from it through the
Janus geometry (``janus_velocity_std``) or from ``dvl_velocity_accuracy``. A recorded
DVL's time-correlated error is the one the
``navigator`` preset measured on a real Navigator (9 mm/s per axis over 19 s): the biases
c_k (per axis of the DVL's velocity) become Gauss-Markov with that std over that time; a
simulated file's own slow error (``dvl_slow_error_std``, ``_time``) likewise, a velocity
error of the DVL's frame that the simulator projects on each beam, held by the three
slow-error states where the beams are measured: four independent beam biases of that
std would put a third of its variance into the vertical (5.2 mm/s where it has 9 at 30
deg) and some into the error velocity, which it has none of. On the 20 held-out
``realistic-maneuvers`` missions of ``beamsnet reproduce adaptive`` the states took the
fixed filter's median final from 1.52 to 1.19 m and its RMSE from 0.95 to 0.68 m (better
on 18 of 20; ``reports/adaptive.md`` before and after the commit that added them, and
its re-run at commit 5f09509: the report has moved since), and
its median velocity NEES from 2.60 to 2.94 (a scratch run on the report's held-out
file). None of it comes from a synthetic protocol's sigma.

Start: a simulated mission at its truth (or drawn around it, ``initial_error_seed``); a
recorded one at its reference's first sample within the IMU's span
(``start_from_reference``: the reference's accuracy, widened by what the vehicle turns,
accelerates and moves in the clock's uncertainty, ``clock_stds``); a recorded one whose log
has no reference attitude, ``coarse_alignment`` (levelling from the averaged
accelerometers, the heading the settings give, ``start_heading_deg``).

A recorded file from ``auvsim check-log --apply`` is read as it is: the IMU's dt from its
times (``imu_rate_hz`` only sets the rounding's density), ``imu_position_body``,
``dvl_position_body``, ``dvl_mounting_rpy_deg``, ``latitude_deg``, ``height_m``,
``gravity`` and the instrument's attributes; the DVL's scale that check-log reports is not
applied to the file, and is what the scale states are for. The mounting and the lever
arm it wrote are known to its standard errors (``applied_dvl_errors``), and the
misalignment and lever-arm states start there instead of at an uncalibrated DVL's 0.5 deg
and 0.1 m: a prior wider than the calibration lets the DVL's slow errors in the turns move
the heading through the misalignment (on the shared segment 4 the filter's yaw
misalignment wandered to -0.33 deg, where check-log knew the mounting to 0.07). The filter
integrates on whatever clock the file's stamps are: it cannot tell stretched stamps from
physical seconds, and a stretch of e makes every integration (angles, velocity,
distance) e too large. check-log therefore puts a file on the clock whose stamps keep
their stated rate: the A-KIT file on the IMU's (on the reference's it would have e =
0.25 % by the publication's stated rates).

Not modelled (they make the filter optimistic where the data have them): the
accelerometers' scale factors and misalignments and the gyros' g-sensitivity (the
gyros' scale factors and misalignments are the states above: without them the filter
took them for accelerometer bias in the turns, up to 28 of its std on a simulated mission,
where the accelerometers' own leave it within 4: ``benchmarks/filter_consistency.py``),
range-dependent noise and heavy-tailed outliers (the gate handles them). The DVL's
sound-speed ratio, a scale factor every beam shares, is held by the scale factors s_k
through a correlated prior (``common_scale_std``, a simulated file's sound-speed
spread). Scored against a
reference, the reported covariance covers the filter's error only, not the reference's
own (a post-processed INS solution: on the A-KIT segment 4 the dead reckoning with the
reference's attitude is as far from the reference as the filter, 4 m).

Speed (``benchmarks/filter.py``, one core): the compiled loop runs at thousands of times
real time; on a recorded 400 s segment with the 29 states, about 5000x, with the
gyro matrix's 38 about 3700x (``docs/performance/results/filter.md``). The first call
compiles the loop (about 30 s) into numba's on-disk cache; later processes load it in
under a second.
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from auvsim.checks import did_you_mean, is_finite
from auvsim.data.beams import beam_matrix
from auvsim.data.checklog import applied_clock_errors, applied_dvl_errors, slow_error
from auvsim.data.files import interrupts_held
from auvsim.data.reader import open_dataset, require_attitude
from auvsim.data.recorded import MAX_RATE, force_slip, rate_slip
from auvsim.errors import DatasetError
from auvsim.physics.earth import earth_rate_ned, normal_gravity
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from beamsnet.data import NO_REFERENCE, DataError, Windows
from beamsnet.estimators.baselines import BeamCalibration
from beamsnet.estimators.registry import Needs, Spec

N_CORE = 15  # p, v, theta, b_a, b_g
N_BEAM = 29  # + 4 scale factors, 4 biases (beams or DVL axes), the DVL's 3 misalignments
# and 3 lever-arm errors
N_SLOW = 3  # the DVL's slow velocity error, its frame's axes, where on (beams)
N_GYRO_MATRIX = 9  # the gyros' scale factors and misalignments, K_g row-major, where on
N_OUT = N_BEAM + N_SLOW + N_GYRO_MATRIX  # the track's instrument-state columns (NaN: off)
N_FEATURES = 6  # what the loop records of each ping for a learned noise model (noisenet)
# The track's columns of the error state, by the FilterTrack field each part fills: the
# rows of P for the core and beam states; the slow-error and gyro-matrix blocks follow, in
# P, whichever blocks before them are on (``_filter``'s si and gi).
_STATES = dict(position=slice(0, 3), velocity=slice(3, 6), attitude=slice(6, 9),
              accel_bias=slice(9, 12), gyro_bias=slice(12, 15), beam_scale=slice(15, 19),
              beam_bias=slice(19, 23), misalignment=slice(23, 26), lever_arm=slice(26, 29),
              slow_error=slice(29, 32), gyro_matrix=slice(32, 41))
_INSTRUMENT_STATES = ("accel_bias", "gyro_bias", "beam_scale", "beam_bias", "misalignment",
                     "lever_arm", "slow_error", "gyro_matrix")  # FilterTrack: each, its std
BEAM_NOISE_FLOOR = 1e-4  # m/s: a noise-free file's beams still get a finite weight
# How well an uncalibrated DVL's mounting is known, deg per axis: our choice for a DVL
# mounted mechanically without an alignment calibration (at 0.5 deg a DVL track bends by
# 0.9 % of the distance; Kinsey, Eustice & Whitcomb 2006, "A survey of underwater vehicle
# navigation", IFAC MCMC, sec. 3.2, on why it matters).
MISALIGNMENT_STD_DEG = 0.5
# How well a recorded log's clocks are put on one another where nothing measured it, s:
# the tolerance ``auvsim check-log``'s targets ask of its clock offsets.
CLOCK_STD = 0.05
# What an IMU sample is (``run_arrays``' ``imu_samples``): a real IMU's, over the interval
# that ends at its time; auvsim's simulated IMU's, held from its time over the next step.
IMU_SAMPLES = ("interval", "held")
# Likewise its lever arm from the IMU, m per axis: the accuracy ``auvsim check-log`` is to
# find lever arms to. A vehicle rolling at 30 deg/s moves a DVL 1.8 m below its IMU at
# 0.9 m/s sideways, so 0.1 m there is 0.05 m/s, over twice a Navigator's noise: the states
# make it observable instead of gated.
LEVER_ARM_STD = 0.1


class NoImuError(DataError):
    """A mission without an ``imu`` group (an imported DVL stream)."""


class SettingsError(ValueError):
    """Settings that ask for states the instrument gives nothing to hold (``run_mission``
    names the mission in a ``DataError``)."""


@dataclass(frozen=True)
class FilterConfig:
    """Settings of the INS/DVL filter. Stds are 1 sigma; None: from the mission (or the
    arrays' instrument arguments). The default initial stds are our choice, of the order
    of a navigation-grade INS aligned at the start of a mission.

    Attributes:
        position_std: initial position error, m per NED axis (a start at the truth or
            given; a start from a reference adds what ``clock_std`` leaves).
        velocity_std: initial velocity error, m/s per NED axis (likewise).
        attitude_std_deg: initial attitude error (level axes, heading), deg; one number
            sets both. From a reference: its accuracy, to which the start adds the
            rotation over ``clock_std``; a coarse alignment has its own.
        start_heading_deg: a recorded mission whose log has no reference attitude starts
            from a coarse alignment (``coarse_alignment``: levelled from the
            accelerometers) on this heading, deg from north; None: such a mission is
            refused. A reference's attitude, where there is one, goes first.
        start_heading_std_deg: that heading's uncertainty, deg (a compass's, say).
        accel_bias_std: initial accelerometer bias std, m/s^2 per axis; None:
            sqrt(turn-on spread^2 + bias instability^2) of the mission's IMU attributes.
        gyro_bias_std: initial gyro bias std, rad/s per axis; None: as above.
        initial_error_seed: None starts exactly at the truth (biases at zero) with the
            covariance above; a seed draws the initial position, velocity and attitude
            errors from it with those stds (simulated missions).
        earth_rate: compensate the Earth's rotation at the latitude; None: whenever the
            latitude is known (a recorded log; a simulated mission with a geographic
            origin), off in auvsim's flat world that does not rotate.
        latitude_deg: deg; None: the mission's ``latitude_deg`` attribute (the arrays'
            ``latitude_deg``).
        gravity: m/s^2 (down); None: the mission's ``gravity`` (the WGS-84 normal
            gravity at the latitude for a recorded log; the arrays': from the latitude).
        beam_states: estimate each measurement's scale factor and bias (8 more states:
            per beam, or per DVL axis for a velocity); None: on for a recorded log, for
            arrays and for a simulated file with a slow DVL error (a real instrument's
            slow errors), off for other simulated missions (white beam noise, as their
            file states).
        slow_error_states: hold the DVL's slow error (its Gauss-Markov velocity error:
            the instrument's std and correlation time, or ``bias_time``) as 3 states, the
            velocity error of the DVL's frame that every beam sees along its direction,
            with the biases c_k constant (``beam_bias_std``); None: on where the beams
            are measured, ``beam_states`` is on and the instrument has a slow error (a
            simulated DVL's is a velocity error, so four independent beam biases would
            put too little of it into the vertical and some into the error velocity,
            which it has none of). Off: the c_k hold it (on a DVL's velocity, per axis,
            the same model).
        gyro_matrix_states: estimate the gyros' scale factors and misalignments, K_g in
            measured w = (I + K_g) w + b_g + noise (9 more states, constant; the module
            docstring's theta' gains -C dK_g w); None: on where either spread is stated,
            by the settings below or by the instrument (a simulated file's IMU config;
            ``run_arrays``'s ``instrument``), off otherwise (a recorded log states none).
        gyro_scale_factor_std: initial std of each scale factor (K_g's diagonal), -; None:
            the instrument's (0 where it states none).
        gyro_misalignment_std: initial std of each of K_g's six off-diagonal elements,
            rad; None: likewise.
        beam_scale_std: initial std of each scale factor, -: 0.2 %, the long-term
            accuracy of a Teledyne RDI Workhorse Navigator (``auvsim.runs.presets
            .navigator`` cites it).
        common_scale_std: the std of a scale factor every measurement shares, -, added
            to the scale factors' prior as a correlated part (``beam_states``); None: the
            instrument's (a simulated DVL's sound-speed spread: every beam is divided by
            the sound-speed ratio; 0 for a recorded log, which states none).
        beam_bias_std: initial std of each bias, m/s: 1 mm/s, likewise.
        misalignment_std_deg: initial std of the DVL's mounting misalignment about each
            of its axes, deg (with ``beam_states``). None: how well the mounting is known,
            the standard errors of a calibration where there is one (a file that ``auvsim
            check-log --apply`` corrected: the mounting it found and wrote, per axis;
            ``run_arrays``'s ``mounting_std_deg``), else a simulated file's drawn spread
            (its DVL config's ``misalignment_std_deg``, where above 0), else
            ``MISALIGNMENT_STD_DEG``. The INS
            cannot tell a heading misalignment from its own heading on a straight leg, so
            this is what makes the position's std grow with distance, and what the DVL's
            slow errors in the turns can move the heading by.
        lever_arm_std: initial std of the DVL's lever arm from the IMU, m per axis
            (with ``beam_states``). None: a calibration's standard errors likewise (the
            lever arm check-log found and wrote), else ``LEVER_ARM_STD``.
        bias_time: correlation time of those biases, s (first-order Gauss-Markov of std
            ``beam_bias_std`` with the instrument's slow error added; with
            ``slow_error_states``, of those states); None: the instrument's slow-error time
            where it has one, else constant.
        gate_probability: chi-square (1 dof) gate on each measurement's normalised
            innovation; 0.999 rejects 0.1 % of good ones (3.29 sigma).
        beam_noise_std: white noise of a beam, m/s (at least ``BEAM_NOISE_FLOOR``); None:
            the mission's instrument (``dvl_noise_std``, at least the floor; the arrays'
            ``instrument.measurement_std``).
        velocity_noise_std: white noise of each axis of a DVL velocity, m/s; None: the
            beam noise (this setting's, else the instrument's) through the Janus geometry
            (``janus_velocity_std``) if known, else the mission's
            ``dvl_velocity_accuracy`` (the arrays' ``instrument.measurement_std``).
        noise_scale: multiplies the DVL's white noise std, the instrument's (with its
            growth with speed) or a setting's: a mis-stated noise on purpose (the learned
            noise model trains at several, ``noisenet.STATED_FACTORS``).
        process_noise_scale: multiplies the std of the IMU's process noise (Q: the white
            noise densities of the accelerometers and gyros and the drive of their biases,
            the instrument's or the settings'): a mis-stated Q on purpose
            (``beamsnet reproduce adaptive`` runs the fixed filter at several to show how
            far any constant Q moves it at sea).
        dvl_updates: False: no measurement is used, pure inertial navigation.
        accel_noise_density: m/s^2/sqrt(Hz); None: the mission's, with a recorded log's
            quantisation added (``quantisation_density``).
        gyro_noise_density: rad/s/sqrt(Hz); None: likewise.
        accel_bias_psd: accelerometer bias random-walk PSD, (m/s^2)^2/s; None:
            2 sigma^2 / tau of the mission's Gauss-Markov bias (its drive, to first order
            in t / tau).
        gyro_bias_psd: gyro bias random-walk PSD, (rad/s)^2/s; None: likewise.
        clock_std: s, how well the streams' clocks are aligned with the reference's: a
            start from a reference is uncertain by what the vehicle moves and turns in
            that time, a ping by what its velocity changes in it. None: a corrected
            file's own figures (how well ``auvsim check-log --apply`` knew the clock
            offsets it applied, ``clock_stds``: the IMU's against the reference's for the
            start, the IMU's and the DVL's together for the pings), else ``CLOCK_STD``.
        watch_pings: the divergence watch's window, pings (0: no watch).
        watch_share: the share of the window's measurements the gate must have rejected
            (with one rejected at the current ping) for the watch to restart the velocity
            from the measurements and widen the attitude and position (an ``Event``).
            A quarter: one DVL axis (or one beam in four) rejected throughout; under the
            gate's own false-alarm rate (0.1 %) a quarter of a window's 30 or more
            measurements (8 or more) has a binomial probability below 1e-15, and a real
            DVL's outliers (0.2 % to a few per cent of pings) stay well below it; on four
            beams, a ping's rejections count only where its beams agree among themselves
            (the module docstring's parity check), so outliers on a fifth of the
            beam-pings restart nothing.
        adaptive: ``"none"``: the measurement noise is the stated one throughout (the
            fixed filter); ``"innovation"``: the stated white noise of the beams (or DVL
            axes) scaled by a factor estimated from the recent innovations (Mohamed &
            Schwarz 1999; the module docstring's "Adaptive measurement noise"). Only R
            is adapted, never Q. ``"learned"``: the DVL's noise (its white R and the
            drive of its slow error's bias states) scaled by a small network's output
            from the recent IMU samples and innovations (``beamsnet.estimators
            .noisenet``, trained on auvsim data; the model's own bounds apply).
        adaptive_window: N, the innovations (of all the DVL's measurements) the estimate
            averages (a sliding window; the first estimate after ``ADAPTIVE_START``).
        adaptive_range: (floor, ceiling), the adapted std's bounds as multiples of the
            stated one (``beam_noise_std``, the instrument's): 0.5 to 10 by default.
        noise_model: the learned noise model's file (``beamsnet reproduce adaptive``
            writes one), for ``adaptive = "learned"`` where no model is given directly.
    """

    position_std: float = 0.1
    velocity_std: float = 0.01
    attitude_std_deg: tuple[float, float] | float = (0.01, 0.05)
    start_heading_deg: float | None = None
    start_heading_std_deg: float = 1.0
    accel_bias_std: float | None = None
    gyro_bias_std: float | None = None
    initial_error_seed: int | None = None
    earth_rate: bool | None = None
    latitude_deg: float | None = None
    gravity: float | None = None
    beam_states: bool | None = None
    slow_error_states: bool | None = None
    gyro_matrix_states: bool | None = None
    gyro_scale_factor_std: float | None = None
    gyro_misalignment_std: float | None = None
    beam_scale_std: float = 0.002
    common_scale_std: float | None = None
    beam_bias_std: float = 0.001
    misalignment_std_deg: float | None = None
    lever_arm_std: float | None = None
    bias_time: float | None = None
    gate_probability: float = 0.999
    beam_noise_std: float | None = None
    velocity_noise_std: float | None = None
    noise_scale: float = 1.0
    process_noise_scale: float = 1.0
    dvl_updates: bool = True
    accel_noise_density: float | None = None
    gyro_noise_density: float | None = None
    accel_bias_psd: float | None = None
    gyro_bias_psd: float | None = None
    clock_std: float | None = None
    watch_pings: int = 10
    watch_share: float = 0.25
    adaptive: str = "none"
    adaptive_window: int = 30
    adaptive_range: tuple[float, float] = (0.5, 10.0)
    noise_model: str | None = None

    def __post_init__(self) -> None:
        for name in _POSITIVE:
            if not (is_finite(value := getattr(self, name)) and value > 0):
                raise ValueError(f"FilterConfig.{name}: expected a positive std, got {value!r}")
        for name in _POSITIVE_OR_NONE:
            if (value := getattr(self, name)) is not None and not (is_finite(value) and value > 0):
                raise ValueError(f"FilterConfig.{name}: expected a positive number or None, "
                                 f"got {value!r}")
        for name in _AT_LEAST_ZERO_OR_NONE:
            if (value := getattr(self, name)) is not None and not (is_finite(value)
                                                                   and value >= 0):
                raise ValueError(f"FilterConfig.{name}: expected a number >= 0 or None, "
                                 f"got {value!r}")
        for name in _BOOL_OR_NONE:
            if not ((value := getattr(self, name)) is None or isinstance(value, bool)):
                raise ValueError(f"FilterConfig.{name}: expected true, false or None, got "
                                 f"{value!r}")
        if not isinstance(self.dvl_updates, bool):
            raise ValueError("FilterConfig.dvl_updates: expected true or false, got "
                             f"{self.dvl_updates!r}")
        heading = self.start_heading_deg
        if heading is not None and not is_finite(heading):
            raise ValueError("FilterConfig.start_heading_deg: expected a heading in deg or "
                             f"None, got {heading!r}")
        seed = self.initial_error_seed
        if seed is not None and not (_whole(seed) and seed >= 0):
            raise ValueError("FilterConfig.initial_error_seed: expected a whole number >= 0 "
                             f"or None, got {seed!r}")
        if is_finite(self.attitude_std_deg):  # one std for all three axes
            object.__setattr__(self, "attitude_std_deg", (float(self.attitude_std_deg),) * 2)
        att = self.attitude_std_deg
        if not (isinstance(att, tuple) and len(att) == 2 and all(is_finite(x) and x > 0
                                                                  for x in att)):
            raise ValueError("FilterConfig.attitude_std_deg: expected two positive stds "
                             f"(level, heading) in deg, got {att!r}")
        if not (is_finite(self.gate_probability) and 0 < self.gate_probability < 1):
            raise ValueError("FilterConfig.gate_probability: expected a probability in "
                             f"(0, 1), got {self.gate_probability!r}")
        if self.latitude_deg is not None and not (is_finite(self.latitude_deg)
                                                  and abs(self.latitude_deg) <= 90):
            raise ValueError("FilterConfig.latitude_deg: expected deg in [-90, 90], got "
                             f"{self.latitude_deg!r}")
        if self.clock_std is not None and not (is_finite(self.clock_std)
                                               and self.clock_std >= 0):
            raise ValueError(f"FilterConfig.clock_std: expected s >= 0, got {self.clock_std!r}")
        if not (_whole(self.watch_pings) and self.watch_pings >= 0):
            raise ValueError("FilterConfig.watch_pings: expected a whole number of pings "
                             f">= 0, got {self.watch_pings!r}")
        if not (is_finite(self.watch_share) and 0 < self.watch_share <= 1):
            raise ValueError("FilterConfig.watch_share: expected a share in (0, 1], got "
                             f"{self.watch_share!r}")
        if self.adaptive not in ADAPTIVE:
            raise ValueError(f"FilterConfig.adaptive: expected one of {', '.join(ADAPTIVE)}, "
                             f"got {self.adaptive!r}")
        if not (_whole(self.adaptive_window) and self.adaptive_window >= 2):
            raise ValueError("FilterConfig.adaptive_window: expected a whole number of "
                             f"innovations >= 2, got {self.adaptive_window!r}")
        if self.noise_model is not None and not isinstance(self.noise_model, str):
            raise ValueError("FilterConfig.noise_model: expected a file's path or None, "
                             f"got {self.noise_model!r}")
        bounds = self.adaptive_range
        if not (isinstance(bounds, tuple) and len(bounds) == 2
                and all(is_finite(x) for x in bounds) and 0 < bounds[0] <= 1 <= bounds[1]):
            raise ValueError("FilterConfig.adaptive_range: expected (floor, ceiling) with "
                             f"0 < floor <= 1 <= ceiling, got {bounds!r}")


# The measurement-noise adaptation: none (the fixed filter), or the innovation-based
# estimate of the scale of the measurements' white noise (``FilterConfig.adaptive``).
ADAPTIVE = ("none", "innovation", "learned")
# No learned noise model: the loop's arguments for one (window 0) that it never reads.
_NO_NET = (0, np.zeros((1, 1)), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1),
           np.ones(1))
# The adapted noise is used once this many innovations are in (or the whole window, if
# shorter); before, the stated noise.
ADAPTIVE_START = 10

# FilterConfig's fields by what they accept (the others are checked one by one).
_POSITIVE = ("position_std", "velocity_std", "beam_scale_std", "beam_bias_std", "noise_scale",
             "process_noise_scale", "start_heading_std_deg")
_POSITIVE_OR_NONE = ("misalignment_std_deg", "lever_arm_std", "bias_time")
_AT_LEAST_ZERO_OR_NONE = ("beam_noise_std", "velocity_noise_std", "gravity", "accel_bias_std",
                          "gyro_bias_std", "accel_noise_density", "gyro_noise_density",
                          "accel_bias_psd", "gyro_bias_psd", "gyro_scale_factor_std",
                          "gyro_misalignment_std", "common_scale_std")
_BOOL_OR_NONE = ("earth_rate", "beam_states", "slow_error_states", "gyro_matrix_states")


def _whole(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def load_config(path) -> FilterConfig:
    """A ``FilterConfig`` from a TOML file whose keys are its fields (any subset; arrays
    for tuples).

    Raises:
        ConfigError: the file cannot be read or parsed, a key is not a field, or a value
            is refused (one line naming it).
    """
    import tomllib

    from auvsim.errors import ConfigError

    try:
        with open(path, "rb") as f:
            table = tomllib.load(f)
    except OSError as e:
        raise ConfigError(f": cannot read {str(path)!r} ({e.strerror})",
                          argument="filter_config") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f": {str(path)!r} is not TOML ({e})",
                          argument="filter_config") from None
    fields = [f.name for f in dataclasses.fields(FilterConfig)]
    unknown = [k for k in table if k not in fields]
    if unknown:
        raise ConfigError(f": {str(path)!r} has key {unknown[0]!r}, which is not a filter "
                          f"setting{did_you_mean(unknown[0], fields)}; expected some of "
                          f"{', '.join(fields)}",
                          argument="filter_config")
    table = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
    try:
        return FilterConfig(**table)
    except ValueError as e:
        raise ConfigError(f": {str(path)!r}: {e}", argument="filter_config") from None


class Start(NamedTuple):
    """Where the filter starts: the body origin's state at IMU time ``time`` and its
    uncertainty (1 sigma each, NED)."""

    time: float  # s, on the IMU's clock
    position_ned: np.ndarray  # (3,) m
    velocity_ned: np.ndarray  # (3,) m/s
    rotation: np.ndarray  # (3, 3) body -> NED
    position_std: np.ndarray  # (3,) m
    velocity_std: np.ndarray  # (3,) m/s
    attitude_std: np.ndarray  # (3,) rad (the global attitude error theta, NED)
    angular_rate: np.ndarray | None = None  # (3,) rad/s body, for the IMU's lever arm
    # at the start (None: the gyros' sample there)


class Event(NamedTuple):
    """A restart by the divergence watch."""

    ping: int  # the ping's index in the track
    time: float  # s
    kind: str  # "restart"
    text: str  # one line, for a report


class FilterTrack(NamedTuple):
    """The filter's output at every DVL ping of one mission (posterior, after the ping's
    measurements). Shapes (P, .); NaN at pings before the filter's start."""

    ping_time: np.ndarray  # (P,) s
    velocity_dvl: np.ndarray  # (P, 3) m/s, DVL frame: the nominal mounting, turned by
    # the estimated misalignment where the beam states are on
    velocity_std: np.ndarray  # (P, 3) m/s
    velocity_cov: np.ndarray  # (P, 3, 3) (m/s)^2
    position_ned: np.ndarray  # (P, 3) m, body origin
    position_std: np.ndarray  # (P, 3) m
    accel_bias: np.ndarray  # (P, 3) m/s^2, body
    accel_bias_std: np.ndarray  # (P, 3)
    gyro_bias: np.ndarray  # (P, 3) rad/s, body
    gyro_bias_std: np.ndarray  # (P, 3)
    beam_scale: np.ndarray  # (P, 4) -, each measurement's scale factor (NaN: no states)
    beam_scale_std: np.ndarray  # (P, 4)
    beam_bias: np.ndarray  # (P, 4) m/s, each measurement's bias (NaN: no states)
    beam_bias_std: np.ndarray  # (P, 4)
    beams_used: np.ndarray  # (P,) int, measurements accepted
    beams_rejected: np.ndarray  # (P,) int, gated out
    nees_velocity: np.ndarray  # (P,) e^T cov^-1 e against the true velocity (NaN: none)
    accepted: np.ndarray  # (P,) bool: the filter accepted a measurement of the ping
    events: tuple[Event, ...] = ()  # the divergence watch's restarts, in time order
    rotation: np.ndarray | None = None  # (P, 3, 3) body -> NED, its attitude
    misalignment: np.ndarray | None = None  # (P, 3) rad, the DVL's, about its axes
    misalignment_std: np.ndarray | None = None  # (P, 3) rad
    lever_arm: np.ndarray | None = None  # (P, 3) m, the DVL's from the IMU, body
    lever_arm_std: np.ndarray | None = None  # (P, 3) m
    slow_error: np.ndarray | None = None  # (P, 3) m/s, the DVL's slow velocity error, its
    # frame (NaN: no states)
    slow_error_std: np.ndarray | None = None  # (P, 3)
    gyro_matrix: np.ndarray | None = None  # (P, 9) the gyros' K_g, row-major: scale
    # factors (-) on its diagonal, misalignments (rad) off it (NaN: no states)
    gyro_matrix_std: np.ndarray | None = None  # (P, 9)
    measurement_std: np.ndarray | None = None  # (P, K) m/s, the white noise of each beam
    # (or DVL axis) for the next ping: the stated one, or the adapted (``adaptive``)
    features: np.ndarray | None = None  # (P, N_FEATURES) what a learned noise model reads
    # of each ping (``beamsnet.estimators.noisemodel.FEATURES``)
    innovation: np.ndarray | None = None  # (P, K) m/s, each measurement's innovation
    # (NaN: not offered)
    innovation_hph: np.ndarray | None = None  # (P, K) (m/s)^2, its predicted h P h^T
    # (with the timing term): the innovation variance less the measurement noise
    innovation_var: np.ndarray | None = None  # (P, K) (m/s)^2, its predicted variance S
    # (h P h^T, the timing term and the measurement noise in use), which the gate used
    stated_std: np.ndarray | None = None  # (P, K) m/s, each measurement's stated white
    # noise at each ping (the instrument's at the ping's speed, or the setting's)
    noise_scale: np.ndarray | None = None  # (P,) the scale of the DVL's noise (white and
    # slow drive) at each ping: 1, or the learned one (the model-based one scales R only)
    noise: Instrument | None = None  # the noise the filter used: the instrument's with the
    # settings applied (scales included; at rest, for a noise that grows with the speed)

    @property
    def availability(self) -> float:
        """Share of the pings whose measurement the filter accepted (not of its finite
        outputs: a filter that has diverged still outputs numbers)."""
        return float(self.accepted.mean()) if len(self.accepted) else math.nan

    @property
    def horizontal_std(self) -> np.ndarray:
        """(P,) m, sqrt(var N + var E) of the position."""
        return np.hypot(self.position_std[:, 0], self.position_std[:, 1])


@numba.njit(cache=True)
def _exp_into(phi, out):
    """out <- the rotation matrix of rotation vector phi (Rodrigues; Groves eq. 2.39)."""
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    if t2 < 1e-12:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    for i in range(3):
        for j in range(3):
            out[i, j] = b * phi[i] * phi[j]  # (1 - cos) / t^2 (phi phi^T - t^2 I) + I
        out[i, i] += 1.0 - b * t2
    out[0, 1] -= a * phi[2]
    out[1, 0] += a * phi[2]
    out[0, 2] += a * phi[1]
    out[2, 0] -= a * phi[1]
    out[1, 2] -= a * phi[0]
    out[2, 1] += a * phi[0]


@numba.njit(cache=True)
def _exp(phi):
    out = np.empty((3, 3))
    _exp_into(phi, out)
    return out


@numba.njit(cache=True)
def _skew(a):
    """(3, 3) [a x], with [a x] b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@numba.njit(cache=True)
def _matmul_into(a, b, out):
    """out <- a b for 3x3 matrices (no BLAS call, no allocation)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@numba.njit(cache=True)
def _phi_apply(x, dt, m_va, m_vba, m_abg, m_vv, m_aa, gi, m_kg, g_dt):
    """x <- Phi x in place for one state vector (a column or row of P): Phi = I + F dt on
    the blocks p<-v, v<-theta, v<-b_a, theta<-b_g, with the Earth rate v<-v, a<-a and the
    gravity's growth with depth v_down<-p_down (``g_dt``: dt dg/d(down), 0 without),
    and where the gyro matrix's states are on (from state ``gi``; -1: off) theta<-K_g."""
    v0, v1, v2 = x[3], x[4], x[5]
    p2 = x[2]
    a0, a1, a2 = x[6], x[7], x[8]
    for r in range(3):
        x[r] += dt * x[3 + r]
        x[3 + r] += (m_va[r, 0] * a0 + m_va[r, 1] * a1 + m_va[r, 2] * a2
                     + m_vba[r, 0] * x[9] + m_vba[r, 1] * x[10] + m_vba[r, 2] * x[11]
                     + m_vv[r, 0] * v0 + m_vv[r, 1] * v1 + m_vv[r, 2] * v2)
        x[6 + r] += (m_abg[r, 0] * x[12] + m_abg[r, 1] * x[13] + m_abg[r, 2] * x[14]
                     + m_aa[r, 0] * a0 + m_aa[r, 1] * a1 + m_aa[r, 2] * a2)
        if gi >= 0:
            acc = 0.0
            for j in range(N_GYRO_MATRIX):
                acc += m_kg[r, j] * x[gi + j]
            x[6 + r] += acc
    if g_dt != 0.0:
        x[5] += g_dt * p2


@numba.njit(cache=True)
def _gyro_rate_into(w_i, bg, kg, gi, out):
    """out <- a gyro sample corrected, rad/s: w - b_g, and where the gyro matrix's states
    are on (``gi`` >= 0) less K_g (w - b_g), the first order of (I + K_g)^-1 (w - b_g)."""
    for r in range(3):
        out[r] = w_i[r] - bg[r]
    if gi >= 0:
        a0, a1, a2 = out[0], out[1], out[2]
        for r in range(3):
            out[r] -= kg[r, 0] * a0 + kg[r, 1] * a1 + kg[r, 2] * a2


@numba.njit(cache=True, inline="always")
def _strapdown(f_i, w_i, h, interval, earth, omega_ie, g_i, p, v, c, ba, bg, kg, gi, vec,
               mat):
    """One IMU step over ``h`` s (the module docstring's mechanisation): ``p``, ``v`` and
    ``c`` moved in place by the specific force ``f_i`` (sample i, or i - 1 held: see
    ``_filter``'s ``interval``) and the rate ``w_i`` (sample i), gravity ``g_i`` at the
    IMU's depth. Leaves what the covariance's step reads: vec[CF] C f (its Earth terms
    included, the Coriolis term not), vec[WR] the rate the gyro matrix's error acts on,
    mat[C_OLD] the attitude before the step. Returns |w_nb| and |f| - g of the sample,
    the noise model's features' sums (``_ping_features``)."""
    fb, wb, cf, dphi, cor, rate, wr = vec[FB], vec[WB], vec[CF], vec[DPHI], vec[COR], \
        vec[RATE], vec[WR]
    rot, c_old, m_c = mat[ROT], mat[C_OLD], mat[M_C]
    for r in range(3):
        fb[r] = f_i[r] - ba[r]
    _gyro_rate_into(w_i, bg, kg, gi, wb)
    if gi >= 0:  # the rate the gyro matrix's error acts on, before the Earth's
        for r in range(3):
            wr[r] = wb[r]
    if earth:  # w_nb = w - C^T Omega_ie, the Earth's rate at sample i's attitude
        for r in range(3):
            dphi[r] = h * wb[r]
        _exp_into(dphi, rot)
        _matmul_into(c, rot, c_old)  # the attitude at sample i, to O(dt Omega_ie)
        np.dot(c_old.T, omega_ie, rate)
        for r in range(3):
            wb[r] -= rate[r]
    if interval:  # C at the interval's middle: C_{i-1} Exp(dt w_nb / 2)
        for r in range(3):
            dphi[r] = 0.5 * h * wb[r]
        _exp_into(dphi, rot)
        _matmul_into(c, rot, m_c)
        for r in range(3):
            cf[r] = m_c[r, 0] * fb[0] + m_c[r, 1] * fb[1] + m_c[r, 2] * fb[2]
    else:
        for r in range(3):
            cf[r] = c[r, 0] * fb[0] + c[r, 1] * fb[1] + c[r, 2] * fb[2]
    if earth:  # C f less the Coriolis term 2 Omega_ie x v
        cor[0] = omega_ie[1] * v[2] - omega_ie[2] * v[1]
        cor[1] = omega_ie[2] * v[0] - omega_ie[0] * v[2]
        cor[2] = omega_ie[0] * v[1] - omega_ie[1] * v[0]
        for r in range(3):
            cf[r] -= 2.0 * cor[r]
    cf[2] += g_i
    # Position: by the new velocity (MuJoCo's step, for held samples), or by the mean of
    # the old and the new (Groves eq. 5.38, for a real IMU's intervals).
    lean = 0.5 * h if interval else 0.0
    for r in range(3):
        v[r] += h * cf[r]
        p[r] += h * (v[r] - lean * cf[r])
        dphi[r] = h * wb[r]
        c_old[r, :] = c[r, :]
    cf[2] -= g_i  # C f (less the Coriolis term) is what the error dynamics see
    turn = math.sqrt(wb[0] * wb[0] + wb[1] * wb[1] + wb[2] * wb[2])
    excess = math.sqrt(fb[0] * fb[0] + fb[1] * fb[1] + fb[2] * fb[2]) - g_i
    if earth:
        for r in range(3):
            cf[r] += 2.0 * cor[r]
    _exp_into(dphi, rot)
    _matmul_into(c_old, rot, c)
    return turn, excess


@numba.njit(cache=True, inline="always")
def _propagate(P, n, h, q, earth, omega_ie, g_grad, gi, vec, mat, m_kg):
    """P <- Phi P Phi^T + Q h over one IMU step (the module docstring's error dynamics),
    from what ``_strapdown`` left in ``vec`` and ``mat``."""
    cf, wr = vec[CF], vec[WR]
    c_old, m_va, m_c, m_vv, m_aa = mat[C_OLD], mat[M_VA], mat[M_C], mat[M_VV], mat[M_AA]
    if earth:  # -2 dt [Omega_ie x] on v <- v, half of it on theta <- theta
        m_vv[0, 1], m_vv[0, 2], m_vv[1, 2] = 2.0 * h * omega_ie[2], \
            -2.0 * h * omega_ie[1], 2.0 * h * omega_ie[0]
        m_vv[1, 0], m_vv[2, 0], m_vv[2, 1] = -m_vv[0, 1], -m_vv[0, 2], -m_vv[1, 2]
        for r in range(3):
            for j in range(3):
                m_aa[r, j] = 0.5 * m_vv[r, j]
    # Phi P Phi^T: columns, then rows of the result.
    m_va[0, 1], m_va[0, 2], m_va[1, 2] = h * cf[2], -h * cf[1], h * cf[0]
    m_va[1, 0], m_va[2, 0], m_va[2, 1] = -h * cf[2], h * cf[1], -h * cf[0]
    for r in range(3):
        for j in range(3):
            m_c[r, j] = -h * c_old[r, j]
    if gi >= 0:  # theta' = -C dK_g w: element (a, b) drives -C[:, a] w_b
        for r in range(3):
            for a_ in range(3):
                for b_ in range(3):
                    m_kg[r, 3 * a_ + b_] = m_c[r, a_] * wr[b_]
    for j in range(n):
        _phi_apply(P[:, j], h, m_va, m_c, m_c, m_vv, m_aa, gi, m_kg, h * g_grad)
    for j in range(n):
        _phi_apply(P[j, :], h, m_va, m_c, m_c, m_vv, m_aa, gi, m_kg, h * g_grad)
    for r in range(3):
        P[3 + r, 3 + r] += q[0] * h
        P[6 + r, 6 + r] += q[1] * h
        P[9 + r, 9 + r] += q[2] * h
        P[12 + r, 12 + r] += q[3] * h


@numba.njit(cache=True, inline="always")
def _decay_slow_error(P, decay, drive, si, cb, se):
    """The DVL's slow error over one IMU step, a first-order Gauss-Markov process: its
    states (the biases c_k where ``si`` < 0, else the velocity error e) times ``decay``
    (1 - h / tau), their variance driven by ``drive`` (PSD times h), (m/s)^2."""
    if si < 0:  # in the biases c_k
        for k in range(4):
            cb[k] *= decay
            P[19 + k, :] *= decay
            P[:, 19 + k] *= decay
            P[19 + k, 19 + k] += drive
    else:  # in the DVL's velocity error e
        for k in range(N_SLOW):
            se[k] *= decay
            P[si + k, :] *= decay
            P[:, si + k] *= decay
            P[si + k, si + k] += drive


@numba.njit(cache=True)
def _parity_agrees(parity, meas, s, cb, r_use, P, nb, gate):
    """Whether a ping's measurements ``meas`` (K,) agree among themselves (the module
    docstring's parity check): a common velocity, misalignment or timing error cancels in
    a . z; an outlier on one beam does not. Its rejections are then the instrument's, not
    the state's."""
    pz, pvar = 0.0, 0.0
    for k in range(meas.shape[0]):
        pz += parity[k] * (meas[k] - cb[k]) / (1.0 + s[k])
        pvar += parity[k] * parity[k] * (r_use[k] + (P[19 + k, 19 + k] if nb > N_CORE
                                                     else 0.0))
    return pz * pz <= gate * pvar


@numba.njit(cache=True)
def _innovation(k, y, dirs, mounting, c, v, wb, w_imu, lever, P, s, cb, mis, se, nb, si, gi,
                hrow):
    """Measurement ``y`` along direction ``k`` (the module docstring's y_k): its
    innovation nu, its Jacobian row (into ``hrow``), P h^T, and the direction in the body
    (gm: where the ping's timing term reads the rate y changes at)."""
    u = c.T @ v + np.cross(wb, lever)  # DVL point velocity, body
    # Direction k of the DVL frame as mounted, in the body: d turned by the
    # misalignment, d + mis x d (d . (x + x x mis) = (d + mis x d) . x).
    d_k = dirs[k] + np.cross(mis, dirs[k])
    gm = mounting @ d_k
    gk = (1.0 + s[k]) * gm
    a = c @ gk
    along = gm[0] * u[0] + gm[1] * u[1] + gm[2] * u[2]
    y_hat = (1.0 + s[k]) * along + cb[k]
    if si >= 0:
        y_hat += dirs[k, 0] * se[0] + dirs[k, 1] * se[1] + dirs[k, 2] * se[2]
    hrow[:] = 0.0
    hrow[3:6] = a
    hrow[6:9] = np.cross(a, v)
    hrow[12:15] = np.cross(gk, lever)
    if nb > N_CORE:
        hrow[15 + k] = along
        hrow[19 + k] = 1.0
        hrow[23:26] = (1.0 + s[k]) * np.cross(dirs[k], mounting.T @ u)
        hrow[26:29] = np.cross(gk, wb)  # g . (w x dL) = dL . (g x w)
    if si >= 0:
        hrow[si:si + N_SLOW] = dirs[k]
    if gi >= 0:  # the rate's error dK_g w in g . (w x L), as b_g's above
        gl = np.cross(gk, lever)
        for a_ in range(3):
            for b_ in range(3):
                hrow[gi + 3 * a_ + b_] = gl[a_] * w_imu[b_]
    return y - y_hat, P @ hrow, gm


@numba.njit(cache=True)
def _correct(P, ph, s_inn, nu, p, v, c, ba, bg, s, cb, mis, lever, se, kg, nb, si, gi):
    """The Kalman update of one accepted measurement (P h^T ``ph``, innovation ``nu`` of
    variance ``s_inn``), and the error estimate injected into the nominal state (which it
    is then reset to 0 from)."""
    gain = ph / s_inn
    dx = gain * nu
    P -= np.outer(gain, ph)
    P[:, :] = 0.5 * (P + P.T)
    p += dx[0:3]
    v += dx[3:6]
    c[:, :] = _exp(dx[6:9]) @ c
    ba += dx[9:12]
    bg += dx[12:15]
    if nb > N_CORE:
        s += dx[15:19]
        cb += dx[19:23]
        mis += dx[23:26]
        lever += dx[26:29]
    if si >= 0:
        se += dx[si:si + N_SLOW]
    if gi >= 0:
        for a_ in range(3):
            for b_ in range(3):
                kg[a_, b_] += dx[gi + 3 * a_ + b_]


@numba.njit(cache=True)
def _ping_features(feat, usable, nu, hph, r_use, r_base, drive, gate, scale_used, acc_w, acc_f,
                   acc_f2, acc_n, v):
    """The noise model's features of a ping (``noisemodel.FEATURES``) into ``feat``: from
    its measurements (``usable``, innovations ``nu``, their h P h^T ``hph``, the variances
    in use and stated, the slow error's drive since the last ping) and from the IMU since
    the last ping (the sums of |w|, of |f| - g and of its squares over ``acc_n``
    samples)."""
    n_dir = nu.shape[0]
    offered, nis_sum, share_sum = 0, 0.0, 0.0
    for k in range(n_dir):
        if usable[k]:
            offered += 1
            s_k = hph[k] + r_use[k]
            nis_sum += min(nu[k] ** 2, gate * s_k) / s_k
            share_sum += min(scale_used * (r_base[k] + drive) / s_k, 1.0)
    mean_w = acc_w / acc_n if acc_n > 0 else 0.0
    mean_f = acc_f / acc_n if acc_n > 0 else 0.0
    var_f = max(acc_f2 / acc_n - mean_f * mean_f, 0.0) if acc_n > 0 else 0.0
    feat[0] = math.log(mean_w + 1e-3)
    feat[1] = math.log(math.sqrt(var_f + mean_f * mean_f) + 1e-3)
    feat[2] = math.log(math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 0.1)
    # The scale the ping's innovations imply, lambda nu^2 / S: the mean NIS times the
    # scale in use, which the noise model's own output does not move (to first order), so
    # that training on its own runs converges (noisenet).
    feat[3] = (math.log(scale_used * nis_sum / offered + 0.01) if offered > 0
               else math.log(0.01))
    feat[4] = share_sum / offered if offered > 0 else 0.0
    feat[5] = offered / n_dir


@numba.njit(cache=True)
def _network_scale(feat_ring, feat_n, net_w1, net_b1, net_w2, net_b2, feat_mean, feat_std,
                   hidden, r_low, r_high):
    """The learned noise model's std scale from the last pings' features (``feat_ring``,
    ``feat_n`` pushed so far; ``beamsnet.estimators.noisenet``), bounded by construction:
    log lambda in (log r_low, log r_high)."""
    net_window = feat_ring.shape[0]
    z = net_b2[0]
    for h_ in range(hidden.shape[0]):
        acc = net_b1[h_]
        for j in range(net_window):  # newest first
            row = feat_ring[(feat_n - 1 - j) % net_window]
            for m_ in range(N_FEATURES):
                col = j * N_FEATURES + m_
                acc += net_w1[h_, col] * (row[m_] - feat_mean[col]) / feat_std[col]
        hidden[h_] = math.tanh(acc)
        z += net_w2[h_] * hidden[h_]
    lo, hi = math.log(r_low), math.log(r_high)
    return math.exp(0.5 * (lo + hi) + 0.5 * (hi - lo) * math.tanh(z))


@numba.njit(cache=True)
def _dvl_velocity(c, v, wb, w_imu, lever, mounting, mis, P, nb, gi):
    """The velocity at the DVL (its frame, m/s) and its covariance: its Jacobian on (dv,
    theta, db_g) and on the states it also depends on where they are on: the lever arm,
    M^T [w x] dL, the misalignment (in the DVL's frame as the filter has it, the nominal
    one turned by mu, a - mu x a = a + a x mu, so [a x] dmu), and the gyro matrix through
    the rate, M^T [L x] e_a w_b per element."""
    extra = (6 if nb > N_CORE else 0) + (N_GYRO_MATRIX if gi >= 0 else 0)
    idx = np.empty(9 + extra, dtype=np.int64)
    jac = np.zeros((3, 9 + extra))
    mt = mounting.T
    jv = mt @ c.T
    ml = mt @ _skew(lever)
    jac[:, 0:3] = jv
    jac[:, 3:6] = jv @ _skew(v)
    jac[:, 6:9] = ml
    for r in range(3):
        idx[r], idx[3 + r], idx[6 + r] = 3 + r, 6 + r, 12 + r
    out = mt @ (c.T @ v + np.cross(wb, lever))
    col = 9
    if nb > N_CORE:
        a_v = out.copy()
        jac[:, col:col + 3] = mt @ _skew(wb)
        jac[:, col + 3:col + 6] = _skew(a_v)
        for r in range(3):
            idx[col + r] = 26 + r
            idx[col + 3 + r] = 23 + r
        col += 6
        out += np.cross(a_v, mis)
    if gi >= 0:
        for a_ in range(3):
            for b_ in range(3):
                jac[:, col] = ml[:, a_] * w_imu[b_]
                idx[col] = gi + 3 * a_ + b_
                col += 1
    sub = np.empty((9 + extra, 9 + extra))
    for a_ in range(9 + extra):
        for b_ in range(9 + extra):
            sub[a_, b_] = P[idx[a_], idx[b_]]
    return out, jac @ sub @ jac.T


@numba.njit(cache=True)
def _record_states(x, sd, P, column, ba, bg, s, cb, mis, lever, se, kg, nb, si, gi):
    """A ping's instrument states (``x``, by ``_STATES``) and every state's std (``sd``,
    sqrt(diag P), by each state's ``column``)."""
    for j in range(P.shape[0]):
        sd[column[j]] = math.sqrt(P[j, j])
    for r in range(3):
        x[9 + r] = ba[r]
        x[12 + r] = bg[r]
    if nb > N_CORE:
        for k in range(4):
            x[15 + k] = s[k]
            x[19 + k] = cb[k]
        for r in range(3):
            x[23 + r] = mis[r]
            x[26 + r] = lever[r]
    if si >= 0:
        for r in range(N_SLOW):
            x[N_BEAM + r] = se[r]
    if gi >= 0:
        for a_ in range(3):
            for b_ in range(3):
                x[N_BEAM + N_SLOW + 3 * a_ + b_] = kg[a_, b_]


@numba.njit(cache=True)
def _restart(P, worst, span, r_max, attitude_prior):
    """The divergence watch's restart: the gate has rejected most measurements for a
    window, so the state, not the instrument, is wrong. The velocity restarts from the
    measurements (its variance covers the worst innovation ``worst``, m/s, and the largest
    stated variance ``r_max``; its correlations dropped), the attitude widens back to its
    prior and the position by what the velocity error could have moved it over the
    window (``span`` s)."""
    for r in range(3):
        for j in range(P.shape[0]):
            P[3 + r, j] = 0.0
            P[j, 3 + r] = 0.0
        P[3 + r, 3 + r] = 4.0 * worst * worst + r_max
        P[6 + r, 6 + r] += attitude_prior[r]
        P[r, r] += (worst * span) ** 2


# The scratch vectors and matrices of ``_filter``'s IMU step, by row (no allocation per
# sample): the corrected specific force and rate, C f, a rotation vector, the Coriolis
# term, the Earth's rate in the body, the gyro matrix's rate; an incremental rotation, the
# attitude before the step, the blocks of Phi.
FB, WB, CF, DPHI, COR, RATE, WR = range(7)
ROT, C_OLD, M_C, M_VA, M_VV, M_AA = range(6)


@numba.njit(cache=True)
def _filter(f, w, dt, g, g_grad, omega_ie, interval, ping_row, meas, usable, dirs, mounting,
            lever, r_imu,
            p, v, c, ba, bg, kg, P, q, r_meas, r_growth, gate, n, si, gi, bias_decay, bias_psd,
            window,
            watch_share, parity, timing_std, adapt_window, r_low, r_high, kappa,
            net_window, net_w1, net_b1, net_w2, net_b2, feat_mean, feat_std):
    """Run the filter over one mission. Arrays are updated in place where they are state
    (p, v, c, ba, bg, P); outputs per ping are returned.

    Args:
        f, w: (N, 3) measured specific force, m/s^2, and angular rate, rad/s, body.
        dt: (N,) s, dt[i] the interval from sample i - 1 to i (dt[0] unused).
        g: gravity at the frame's origin (down position 0), m/s^2 (down). g_grad: its
            growth with the down position, m/s^2 per m (0: the same everywhere).
        omega_ie: (3,) Earth rate, NED.
        interval: the IMU's samples describe the interval that ends at their time (a real
            IMU's), so the step from i - 1 to i takes f[i] at the interval's middle
            attitude and moves by the mean of the old and new velocity; else sample i - 1
            is held over it and the step moves by the new velocity (auvsim's simulated
            IMU, MuJoCo's semi-implicit Euler step).
        ping_row: (P,) IMU sample of each ping (-1: before the start, skipped).
        meas: (P, K) m/s, K <= 4 scalar measurements per ping along ``dirs``.
        usable: (P, K) bool. dirs: (K, 3) unit directions in the DVL frame (beams, or
        the DVL's axes for its velocity). mounting: (3, 3) DVL -> body.
        lever: (3,) r_dvl - r_imu. r_imu: (3,) IMU position in the body, m.
        p, v, c, ba, bg: initial IMU-point position, velocity, rotation, biases.
        kg: (3, 3) initial gyro matrix K_g (measured w = (I + K_g) w + b_g + noise: its
            diagonal the scale factors, the rest the misalignments), used where ``gi`` >= 0.
        P: (n, n) initial covariance. q: (4,) PSDs (accel, gyro white noise; accel, gyro
            bias random walk). r_meas: (K,) measurement variances at rest, (m/s)^2.
        r_growth: (K,) m/s per m/s: each measurement's white std grows by this times the
            DVL point's speed (predicted at the ping), the instrument's law; where 0 the
            variance is ``r_meas`` exactly.
        gate: chi-square threshold. n: states, ``N_CORE`` (15) or ``N_BEAM`` (29), plus
            ``N_SLOW`` (3) and ``N_GYRO_MATRIX`` (9) where those are on, in that order.
        gi: the first of the gyro matrix's states (``n - N_GYRO_MATRIX``), or -1: off.
        si: the first of the DVL's slow velocity error's states (3, Gauss-Markov, in the
            DVL frame: measurement k gains d_k . e), or -1: the measurement biases c_k
            hold the slow error instead.
        bias_decay: 1 / correlation time of the slow error (the states e where ``si`` >=
            0, else the measurement biases c_k), 1/s (0: constant).
        bias_psd: its driving PSD, (m/s)^2/s.
        window, watch_share: the divergence watch's window, pings (0: off), and the share
            of its measurements the gate must have rejected.
        parity: (K,) unit vector a with a^T dirs = 0 (four beams: the Janus error
            velocity's combination), or zeros (no redundancy): a ping whose K
            measurements disagree among themselves (a . z beyond the gate, z the
            measurements less their biases and scale factors) holds an outlier, and its
            rejections do not count towards the watch.
        timing_std: s, the std of each ping's time on the IMU's clock: a measurement
            along b changes at b . du/dt, so it is uncertain by timing_std |b . du/dt|
            more (du/dt = f + C^T g - w x u + alpha x L, u the DVL point's body velocity).
        adapt_window: N, the last innovations (of all the measurements, gated or not)
            whose mean gives the noise's scale (0: the fixed filter, ``r_meas``
            throughout).
        r_low, r_high: the bounds of the adapted variances' ratio to ``r_meas``.
        kappa: E[min(nu^2, gate S)] / S of a consistent filter's innovations.
        net_window: W, the pings of features the learned noise model reads (0: no
            model). net_w1 (H, W F), net_b1 (H,), net_w2 (H,), net_b2 (1,): its layers;
            feat_mean, feat_std (W F,): its inputs' normalisation
            (``beamsnet.estimators.noisenet``). With it, the measurements' variances and
            the biases' drive are r_meas and bias_psd times its output from the next ping
            on (``adapt_window`` must be 0).
    """
    n_ping = ping_row.shape[0]
    n_dir = dirs.shape[0]
    out_v = np.full((n_ping, 3), np.nan)
    out_cov = np.full((n_ping, 3, 3), np.nan)
    out_p = np.full((n_ping, 3), np.nan)
    out_x = np.full((n_ping, N_OUT), np.nan)  # the instrument states, by _STATES
    out_sd = np.full((n_ping, N_OUT), np.nan)  # sqrt(diag P), by _STATES
    nb = si if si >= 0 else gi if gi >= 0 else n  # the core and beam states
    column = np.arange(n)  # each state's column of the track (_STATES)
    if si >= 0:
        column[si:si + N_SLOW] = np.arange(N_BEAM, N_BEAM + N_SLOW)
    if gi >= 0:
        column[gi:gi + N_GYRO_MATRIX] = np.arange(N_BEAM + N_SLOW, N_OUT)
    out_c = np.full((n_ping, 3, 3), np.nan)
    used = np.zeros(n_ping, dtype=np.int64)
    rejected = np.zeros(n_ping, dtype=np.int64)
    reset = np.zeros(n_ping, dtype=np.bool_)
    out_r = np.full((n_ping, n_dir), np.nan)  # the variance each measurement had, (m/s)^2
    out_feat = np.full((n_ping, N_FEATURES), np.nan)  # the noise model's inputs, per ping
    out_nu = np.full((n_ping, n_dir), np.nan)  # each measurement's innovation, m/s
    out_hph = np.full((n_ping, n_dir), np.nan)  # its h P h^T + timing term, (m/s)^2
    out_s = np.full((n_ping, n_dir), np.nan)  # its variance, S = that + R, (m/s)^2
    # The IMU since the last ping, for the features: sum |w|, sum (|f| - g), its squares.
    acc_w, acc_f, acc_f2, acc_n = 0.0, 0.0, 0.0, 0
    # The slow error's drive into each bias c_k since the last ping, unscaled, (m/s)^2;
    # the drive in use (bias_psd, or scaled by the noise model), and the scale in use.
    drive, bias_psd_use, scale_used = 0.0, bias_psd, 1.0
    out_scale = np.full(n_ping, np.nan)
    feat_ring = np.zeros((max(net_window, 1), N_FEATURES))
    feat_n = 0
    hidden = np.zeros(net_b1.shape[0])
    r_base = r_meas.copy()  # the ping's stated variances (r_meas, grown with the speed)
    r_use = r_meas.copy()  # the variances in use: r_base, or adapted (times mult)
    mult = 1.0  # the adapted variances' ratio to the stated ones, from the last ping
    out_stated = np.full((n_ping, n_dir), np.nan)  # each ping's stated std, m/s
    ring = np.zeros(max(adapt_window, 1))  # the last innovations' white-noise ratios
    ring_n = 0
    adapt_start = min(adapt_window, ADAPTIVE_START)
    ring_used = np.zeros(max(window, 1), dtype=np.int64)
    ring_rejected = np.zeros(max(window, 1), dtype=np.int64)
    attitude_prior = np.array([P[6, 6], P[7, 7], P[8, 8]])
    s = np.zeros(4)
    cb = np.zeros(4)
    mis = np.zeros(3)  # the DVL frame's small rotation from its nominal mounting, rad
    se = np.zeros(3)  # the DVL's slow velocity error, its frame, m/s (where si >= 0)
    earth = omega_ie[0] != 0.0 or omega_ie[1] != 0.0 or omega_ie[2] != 0.0
    check_parity = np.abs(parity).sum() > 0.0
    k_ping = 0
    while k_ping < n_ping and ping_row[k_ping] < 0:
        k_ping += 1
    hrow = np.zeros(n)
    vec = np.zeros((7, 3))  # the IMU step's scratch (FB ... WR)
    mat = np.zeros((6, 3, 3))  # (ROT ... M_AA)
    m_kg = np.zeros((3, N_GYRO_MATRIX))  # -dt C [w^T in row a] on theta <- K_g
    w_imu = np.zeros(3)  # the corrected gyro sample at a ping
    for i in range(f.shape[0]):
        if i > 0:
            h = dt[i]
            g_i = g + g_grad * p[2] if g_grad != 0.0 else g  # at the IMU's depth at i - 1
            turn, excess = _strapdown(f[i if interval else i - 1], w[i], h, interval, earth,
                                      omega_ie, g_i, p, v, c, ba, bg, kg, gi, vec, mat)
            acc_w += turn
            acc_f += excess
            acc_f2 += excess * excess
            acc_n += 1
            _propagate(P, n, h, q, earth, omega_ie, g_grad, gi, vec, mat, m_kg)
            if nb > N_CORE and bias_decay > 0.0:  # the first-order Gauss-Markov slow error
                decay = 1.0 - h * bias_decay
                _decay_slow_error(P, decay, bias_psd_use * h, si, cb, se)
                drive = drive * decay * decay + bias_psd * h
        while k_ping < n_ping and ping_row[k_ping] == i:
            # The DVL's lever arm turns with the body relative to the Earth: w_nb.
            _gyro_rate_into(w[i], bg, kg, gi, w_imu)
            wb = w_imu - c.T @ omega_ie
            worst = 0.0
            # The instrument's white noise at the DVL point's predicted speed (u: its
            # velocity, body, before the ping's updates), and the adaptation.
            u = c.T @ v + np.cross(wb, lever)
            speed = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
            for k in range(n_dir):
                if r_growth[k] != 0.0:
                    r_base[k] = (math.sqrt(r_meas[k]) + r_growth[k] * speed) ** 2
                r_use[k] = mult * r_base[k]
                out_stated[k_ping, k] = math.sqrt(r_base[k])
            agree = True
            if check_parity and usable[k_ping].all():
                agree = _parity_agrees(parity, meas[k_ping], s, cb, r_use, P, nb, gate)
            u_dot = np.zeros(3)
            if timing_std > 0.0:
                alpha = (w[i] - w[i - 1]) / dt[i] if i > 0 else np.zeros(3)
                u_dot = (f[i] - ba + (g + g_grad * p[2]) * c[2, :] - np.cross(wb, u)
                         + np.cross(alpha, lever))
            for k in range(n_dir):
                if not usable[k_ping, k]:
                    continue
                nu, ph, gm = _innovation(k, meas[k_ping, k], dirs, mounting, c, v, wb, w_imu,
                                         lever, P, s, cb, mis, se, nb, si, gi, hrow)
                rate_k = gm[0] * u_dot[0] + gm[1] * u_dot[1] + gm[2] * u_dot[2]
                hph = hrow @ ph
                s_inn = hph + r_use[k] + (timing_std * rate_k) ** 2
                out_nu[k_ping, k] = nu
                out_hph[k_ping, k] = hph + (timing_std * rate_k) ** 2
                out_s[k_ping, k] = s_inn
                if adapt_window > 0:
                    # This innovation's share of the window (the module docstring): nu^2
                    # winsorised at the gate, less its predicted h P h^T, per stated
                    # variance.
                    ring[ring_n % adapt_window] = (
                        min(nu * nu, gate * s_inn) / kappa - hph
                        - (timing_std * rate_k) ** 2) / r_base[k]
                    ring_n += 1
                if nu * nu > gate * s_inn:
                    rejected[k_ping] += 1
                    worst = max(worst, abs(nu))
                    continue
                used[k_ping] += 1
                _correct(P, ph, s_inn, nu, p, v, c, ba, bg, s, cb, mis, lever, se, kg, nb, si,
                         gi)
            held = min(ring_n, adapt_window)
            if adapt_window > 0 and held >= adapt_start:
                # Innovation-based R (the module docstring), for the next ping's updates:
                # the stated variances times the window's mean ratio, bounded.
                mult = min(max(ring[:held].sum() / held, r_low), r_high)
                for k in range(n_dir):
                    r_use[k] = mult * r_base[k]
            # The noise model's features of this ping, and its scale for the next ping's
            # measurements.
            out_scale[k_ping] = scale_used
            _ping_features(out_feat[k_ping], usable[k_ping], out_nu[k_ping], out_hph[k_ping],
                           r_use, r_base, drive, gate, scale_used, acc_w, acc_f, acc_f2,
                           acc_n, v)
            drive = 0.0
            acc_w, acc_f, acc_f2, acc_n = 0.0, 0.0, 0.0, 0
            if net_window > 0:
                if feat_n == 0:  # the first ping's features fill the window
                    for j in range(net_window):
                        feat_ring[j] = out_feat[k_ping]
                feat_ring[feat_n % net_window] = out_feat[k_ping]
                feat_n += 1
                scale_used = _network_scale(feat_ring, feat_n, net_w1, net_b1, net_w2,
                                            net_b2, feat_mean, feat_std, hidden, r_low, r_high)
                mult = scale_used
                for k in range(n_dir):
                    r_use[k] = mult * r_base[k]
                bias_psd_use = scale_used * bias_psd
            if window > 0:
                slot = k_ping % window
                ring_used[slot] = used[k_ping] + rejected[k_ping]
                ring_rejected[slot] = rejected[k_ping] if agree else 0
                offered = ring_used.sum()
                if (ring_rejected[slot] > 0 and offered >= window
                        and ring_rejected.sum() >= watch_share * offered):
                    first = ping_row[max(0, k_ping - window + 1)]
                    span = (i - first) * dt[i] if first >= 0 else 0.0  # the window, s
                    _restart(P, worst, span, r_base.max(), attitude_prior)
                    reset[k_ping] = True
                    ring_used[:] = 0
                    ring_rejected[:] = 0
            _gyro_rate_into(w[i], bg, kg, gi, w_imu)  # after the ping's updates
            wb = w_imu - c.T @ omega_ie
            out_v[k_ping], out_cov[k_ping] = _dvl_velocity(c, v, wb, w_imu, lever, mounting,
                                                           mis, P, nb, gi)
            out_p[k_ping] = p - c @ r_imu
            out_c[k_ping] = c
            out_r[k_ping] = r_use
            # The origin's position error adds theta x (C r_imu); r_imu is short, and its
            # share is below the position std's first digit: the IMU point's std.
            _record_states(out_x[k_ping], out_sd[k_ping], P, column, ba, bg, s, cb, mis,
                           lever, se, kg, nb, si, gi)
            k_ping += 1
    return (out_v, out_cov, out_p, out_x, out_sd, used, rejected, reset, out_c, out_r,
            out_feat, out_nu, out_hph, out_scale, out_stated, out_s)


def _dataset_config(mission) -> dict:
    text = mission.dataset.config_json
    return json.loads(text) if text else {}


def janus_velocity_std(beam_noise_std: float, beam_angle_deg: float) -> np.ndarray:
    """(3,) m/s, the white noise of each axis of the velocity a 4-beam Janus DVL solves
    from beams of white noise ``beam_noise_std`` (independent, equal) at
    ``beam_angle_deg`` from the vertical: v_x = (b1 - b2) / (2 sin a) and likewise y,
    v_z = (b1 + b2 + b3 + b4) / (4 cos a) (Teledyne RD Instruments, "ADCP Coordinate
    Transformation: Formulas and Calculations", P/N 951-6079-00, 2010, sec. 5), so
    sigma_x = sigma_y = sigma / (sqrt 2 sin a) and sigma_z = sigma / (2 cos a)."""
    a = math.radians(beam_angle_deg)
    return beam_noise_std * np.array([1 / (math.sqrt(2) * math.sin(a)),
                                      1 / (math.sqrt(2) * math.sin(a)), 0.5 / math.cos(a)])


def quantisation_density(samples: np.ndarray, rate_hz: float) -> float:
    """The white-noise density, per sqrt(Hz), of a log's rounding: its step q (the
    smallest nonzero difference between the distinct values the log holds) gives a
    uniform error of variance q^2 / 12 in every sample (Widrow & Kollar 2008,
    "Quantization Noise", ch. 4), white over the band rate/2: q / sqrt(12 rate)."""
    values = np.unique(np.asarray(samples, dtype=float))
    steps = np.diff(values)
    steps = steps[steps > 1e-12 * max(1.0, float(np.abs(values).max(initial=0.0)))]
    if not len(steps):
        return 0.0
    return float(steps.min()) / math.sqrt(12.0 * rate_hz)


ALIGN_S = 10.0  # s of IMU samples a coarse alignment averages


def dvl_acceleration(dvl_time, velocity_dvl, mounting: np.ndarray, imu_time, angular_rate,
                     seconds: float = ALIGN_S) -> np.ndarray:
    """(3,) m/s^2, the body's mean acceleration over the first ``seconds`` of the IMU's
    span as the DVL shows it: a_b = dv_b/dt + w x v_b (the body velocity's change, and
    the turn of it), from the first and the last valid ping within the span (their
    velocities in the DVL frame, turned to the body by ``mounting``) and the mean body
    rate ``angular_rate`` (N, 3) rad/s over it; zeros with fewer than two such pings."""
    t = np.asarray(dvl_time, dtype=float)
    v = np.asarray(velocity_dvl, dtype=float) @ np.asarray(mounting, dtype=float).T
    t_imu = np.asarray(imu_time, dtype=float)
    inside = np.flatnonzero((t >= t_imu[0]) & (t <= t_imu[0] + seconds)
                            & np.isfinite(v).all(axis=1))
    if len(inside) < 2:
        return np.zeros(3)
    first, last = inside[0], inside[-1]
    rate = np.asarray(angular_rate, dtype=float)[t_imu <= t_imu[0] + seconds].mean(axis=0)
    return (v[last] - v[first]) / (t[last] - t[first]) + np.cross(rate, v[inside].mean(axis=0))


def start_from_reference(time: float, position_ned, velocity_ned, rotation, *,
                         angular_rate, acceleration=None,
                         config: FilterConfig = FilterConfig(),
                         clock_std: float | None = None) -> Start:
    """A start at a reference's sample (its ``time`` on the IMU's clock; the body origin's
    position (3,) m, NED velocity (3,) m/s and body -> NED rotation (3, 3)), uncertain by
    the reference's own accuracy (``config``'s position, velocity and attitude stds) and
    by what a clock error of ``clock_std`` s makes of it (None: ``config.clock_std``, else
    ``CLOCK_STD``): the rotation over that time, |w| clock_std for the body rate
    ``angular_rate`` (3,) rad/s there (a vehicle that starts rolling at 33 deg/s is 1.7
    deg off in roll for 0.05 s), the velocity change |a| clock_std, the distance |v|
    clock_std."""
    if clock_std is None:
        clock_std = _clock_setting(config)
    level, heading = np.radians(config.attitude_std_deg)
    rotation = np.asarray(rotation, dtype=float)
    turned = np.abs(rotation @ np.asarray(angular_rate, dtype=float)) * clock_std
    accel = np.zeros(3) if acceleration is None else np.asarray(acceleration, dtype=float)
    velocity_ned = np.asarray(velocity_ned, dtype=float)
    return Start(
        time=float(time), position_ned=np.asarray(position_ned, dtype=float),
        velocity_ned=velocity_ned, rotation=rotation,
        position_std=np.hypot(config.position_std, np.abs(velocity_ned) * clock_std),
        velocity_std=np.hypot(config.velocity_std, np.abs(accel) * clock_std),
        attitude_std=np.hypot(np.array([level, level, heading]), turned))


def coarse_alignment(imu_time, specific_force, *, heading_deg: float, position_ned=(0, 0, 0),
                     velocity_ned=(0, 0, 0), heading_std_deg: float = 1.0,
                     seconds: float = ALIGN_S, speed_std: float = 0.5,
                     position_std: float = 1.0, acceleration_body=(0, 0, 0)) -> Start:
    """A start without a reference: level from the accelerometers averaged over the first
    ``seconds`` (gravity is a - f: at rest -f on average, roll = atan2(-f_y, -f_z), pitch
    = atan2(f_x, |(f_y, f_z)|); Groves 2013 sec. 5.6.2), less the body's mean acceleration
    over the window where it is known (``acceleration_body``, m/s^2: a vehicle that
    speeds up or turns while it is averaged; ``dvl_acceleration``), heading given. The
    level std is the spread of the tilt over the window (what the motion leaves in the
    average) over sqrt of its independent seconds, at least 1 mrad (our floor, ten times
    what a navigation-grade accelerometer's 100 micro-g bias tilts). The velocity is given
    (default at rest), with ``speed_std`` per axis, the position ``position_std``; the DVL
    corrects the velocity and the level within pings."""
    t = np.asarray(imu_time, dtype=float)
    f = np.asarray(specific_force, dtype=float) - np.asarray(acceleration_body, dtype=float)
    rows = t <= t[0] + seconds
    mean = f[rows].mean(axis=0)
    roll = math.atan2(-mean[1], -mean[2])
    pitch = math.atan2(mean[0], math.hypot(mean[1], mean[2]))
    g = float(np.linalg.norm(mean))
    # Per second, the tilt the mean specific force shows: its spread is what the motion
    # leaves in the average.
    seconds_of = np.floor(t[rows] - t[0]).astype(int)
    per_second = np.stack([f[rows][seconds_of == k].mean(axis=0)
                           for k in np.unique(seconds_of)])
    tilt = np.linalg.norm(per_second[:, :2] - mean[:2], axis=1) / g
    level = max(float(np.sqrt(np.mean(tilt**2) / max(len(per_second), 1))), 1e-3)
    return Start(time=float(t[0]), position_ned=np.asarray(position_ned, dtype=float),
                 velocity_ned=np.asarray(velocity_ned, dtype=float),
                 rotation=rotation_rpy(roll, pitch, math.radians(heading_deg)),
                 position_std=np.full(3, position_std), velocity_std=np.full(3, speed_std),
                 attitude_std=np.array([level, level, math.radians(heading_std_deg)]))


class Instrument(NamedTuple):
    """An IMU's and a DVL's error specifications, as the filter uses them (1 sigma)."""

    accel_noise_density: float  # m/s^2/sqrt(Hz)
    gyro_noise_density: float  # rad/s/sqrt(Hz)
    accel_bias_std: float  # m/s^2, initial
    gyro_bias_std: float  # rad/s, initial
    accel_bias_psd: float  # (m/s^2)^2/s
    gyro_bias_psd: float  # (rad/s)^2/s
    measurement_std: np.ndarray  # (K,) m/s, white noise of each beam (K = 4, given beams)
    # or velocity axis (K = 3, given a velocity), or one number for all (NaN: not stated;
    # the settings' ``beam_noise_std`` or ``velocity_noise_std`` give it)
    noise_growth: np.ndarray | float = 0.0  # (K,) m/s per m/s: how much that noise grows
    # with the DVL's speed (a simulated instrument's ``noise_speed_coeff``, per beam or
    # through the Janus geometry per axis); the noise at speed U is measurement_std +
    # noise_growth U
    slow_error_std: float = 0.0  # m/s, the DVL's time-correlated velocity error per axis
    slow_error_time: float | None = None  # s, its correlation time (Gauss-Markov)
    common_scale_std: float = 0.0  # -, a scale factor every measurement shares (a DVL's
    # sound-speed ratio: its beams are all divided by it)
    gyro_scale_factor_std: float = 0.0  # -, each gyro's scale-factor error
    gyro_misalignment_std: float = 0.0  # rad, each of the gyro triad's six cross-couplings


def nearest_samples(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(P,) the index of the sample of ``t`` (increasing, s) nearest each of ``times`` (s);
    -1 for a time more than half a sample before the first (no sample holds it)."""
    t, times = np.asarray(t, dtype=float), np.asarray(times, dtype=float)
    if len(t) < 2:
        return np.where(times < t[0], -1, 0).astype(np.int64)
    after = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    before = after - 1
    out = np.where(np.abs(times - t[before]) <= np.abs(t[after] - times), before, after)
    return np.where(times < t[0] - 0.5 * (t[1] - t[0]), -1, out).astype(np.int64)


def run_arrays(imu_time, specific_force, angular_rate, dvl_time, *, beams=None,
               velocity=None, valid=None, beam_angle_deg: float | None = None,
               mounting_rpy_deg=(0.0, 0.0, 0.0), imu_position_body=(0.0, 0.0, 0.0),
               dvl_position_body=(0.0, 0.0, 0.0), start: Start,
               instrument: Instrument, latitude_deg: float | None = None,
               height_m: float = 0.0, gravity: float | None = None,
               config: FilterConfig = FilterConfig(), truth_velocity_dvl=None,
               ping_row=None, timing_std: float | None = None, mounting_std_deg=None,
               dvl_position_std=None, noise_model=None,
               imu_samples: str = "interval") -> FilterTrack:
    """Run the filter on arrays: no dataset needed.

    The streams keep their own clocks: each DVL ping is applied at the IMU sample nearest
    its time (``nearest_samples``), nothing is resampled; pings before ``start.time`` are
    left out (NaN, not accepted).

    Args:
        imu_time: (N,) s, increasing. specific_force: (N, 3) m/s^2 and angular_rate:
            (N, 3) rad/s, body FRD at the IMU.
        dvl_time: (P,) s on the IMU's clock.
        beams: (P, 4) m/s, each Janus beam's velocity (``auvsim.data.beams``), or
        velocity: (P, 3) m/s, the DVL's own velocity in its frame: one of the two.
        valid: (P, 4) or (P, 3) or (P,) bool, which measurements to use (default: the
            finite ones).
        beam_angle_deg: the beams' angle from the vertical (needed with ``beams``; with
            a ``velocity``, turns ``config.beam_noise_std`` into its axes' noise).
        mounting_rpy_deg: (3,) DVL frame -> body, deg. imu_position_body,
            dvl_position_body: (3,) m, FRD from the body origin (the reference point).
        mounting_std_deg, dvl_position_std: (3,) deg and m, how well the mounting and
            the DVL's position are known (a calibration's standard errors), where
            ``config`` leaves them open (None there); None here: ``MISALIGNMENT_STD_DEG``
            and ``LEVER_ARM_STD``.
        start: where and how sure the filter starts (``start_from_reference``,
            ``coarse_alignment``, or the truth).
        instrument: the IMU's and DVL's noise (``Instrument``).
        latitude_deg: the place (``config.latitude_deg`` overrides it); with it (unless
            ``config.earth_rate`` is False) the Earth's rate is compensated and gravity is
            WGS-84's normal gravity there (``auvsim.physics.earth``). None: a flat Earth
            that does not rotate.
        height_m: height for the normal gravity, m (negative under water).
        gravity: m/s^2, overrides both (``config.gravity`` overrides it).
        config: settings; a setting wins over the argument it names (its instrument
            fields, ``beam_noise_std`` and ``velocity_noise_std`` over ``instrument``'s).
        truth_velocity_dvl: (P, 3) m/s, for the NEES (NaN without).
        ping_row: (P,) the IMU sample of each ping, where a file states it (simulated
            missions' ``imu/index_of_dvl``); default from the times.
        timing_std: s, how uncertain each ping's time is on the IMU's clock; None:
            ``config.clock_std``, else ``CLOCK_STD`` (``run_mission``: a corrected
            file's own figure; 0 for a simulated mission, whose clocks are exact).
        noise_model: with ``config.adaptive = "learned"``, the learned noise model
            (``beamsnet.estimators.noisenet.NoiseModel``); None: read from
            ``config.noise_model``.
        imu_samples: what an IMU sample is (``IMU_SAMPLES``): ``"interval"``, a real
            IMU's, the specific force over the interval that ends at its time (its average,
            or its increment over the interval's length), which the step to it turns by
            the attitude at the interval's middle; ``"held"``, auvsim's simulated IMU's,
            sample i - 1 held over the step to i (``run_mission`` chooses by the
            mission's origin).

    Returns:
        The track at every ping.

    Raises:
        ValueError: an argument of the wrong shape, order or value, named
            (``SettingsError``: settings asking for states the instrument gives nothing to
            hold).
    """
    t = np.asarray(imu_time, dtype=float)
    f = np.ascontiguousarray(specific_force, dtype=np.float64)
    w = np.ascontiguousarray(angular_rate, dtype=np.float64)
    if t.ndim != 1 or len(t) < 2 or f.shape != (len(t), 3) or w.shape != (len(t), 3):
        raise ValueError(f"imu_time, specific_force, angular_rate: expected (N,), (N, 3), "
                         f"(N, 3) with N >= 2, got {t.shape}, {f.shape}, {w.shape}")
    if not (np.diff(t) > 0).all():
        raise ValueError("imu_time: expected increasing times")
    for name, x in (("specific_force", f), ("angular_rate", w)):
        bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
        if bad.size:  # one would make every state after it NaN, and still "accepted"
            raise ValueError(f"{name}: expected finite samples, got {x[bad[0]].tolist()} "
                             f"at sample {bad[0]} (t = {t[bad[0]]:g} s)"
                             + (f" and {bad.size - 1} more" if bad.size > 1 else "")
                             + "; drop or fill them first")
    # Values no vehicle's IMU reads in SI units: another unit (auvsim import's rule).
    k = rate_slip(w)
    if k is not None:
        raise ValueError(f"angular_rate: reaches {np.linalg.norm(w[k]):.4g} rad/s at sample "
                         f"{k} (t = {t[k]:g} s), beyond a full turn per second, as "
                         f"{100 * np.mean(np.linalg.norm(w, axis=1) > MAX_RATE):.1f} % of the "
                         "samples do; expected rad/s (in deg/s? np.radians them first)")
    if imu_samples not in IMU_SAMPLES:
        raise ValueError(f"imu_samples: expected one of {', '.join(IMU_SAMPLES)}, got "
                         f"{imu_samples!r}")
    tp = np.asarray(dvl_time, dtype=float)
    if tp.ndim != 1 or not np.isfinite(tp).all():
        raise ValueError(f"dvl_time: expected (P,) finite times, got shape {tp.shape}")
    # A ping may lie a ping's interval (at most 1 s) beyond the IMU's ends (a clock offset
    # check-log applied leaves the last one 20 ms past); further, applied at the nearest
    # sample, it would be a stamp in another unit or of another log.
    slack = max(min(float(np.median(np.diff(tp))), 1.0) if len(tp) > 1 else 0.0,
                10.0 * float(np.median(np.diff(t))))
    outside = (tp < t[0] - slack) | (tp > t[-1] + slack)
    if outside.any():
        k = np.flatnonzero(outside)[0]
        raise ValueError(f"dvl_time: {outside.sum()} ping(s) outside the IMU's span "
                         f"{t[0]:g} to {t[-1]:g} s (the first at {tp[k]:g} s); expected "
                         "pings on the IMU's clock, in s, within its samples")
    if not (t[0] <= start.time <= t[-1]):
        raise ValueError(f"start: its time {start.time:g} s is outside the IMU's span "
                         f"{t[0]:g} to {t[-1]:g} s; expected a start among the samples")
    if (beams is None) == (velocity is None):
        raise ValueError("beams, velocity: expected one of the two")
    if beams is not None:
        meas = np.asarray(beams, dtype=float)
        if beam_angle_deg is None:
            raise ValueError("beam_angle_deg: expected the beams' angle with beams")
        if not 0.0 < float(beam_angle_deg) < 90.0:  # NaN too
            raise ValueError(f"beam_angle_deg: expected deg from the vertical in (0, 90), "
                             f"got {beam_angle_deg!r}")
        dirs = beam_matrix(math.radians(float(beam_angle_deg)))
    else:
        meas = np.asarray(velocity, dtype=float)
        dirs = np.eye(3)
    if meas.shape != (len(tp), len(dirs)):
        raise ValueError(f"{'beams' if beams is not None else 'velocity'}: expected shape "
                         f"({len(tp)}, {len(dirs)}), got {meas.shape}")
    usable = np.isfinite(meas)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape not in ((len(tp),), meas.shape):
            raise ValueError(f"valid: expected shape ({len(tp)},) or {meas.shape}, got "
                             f"{valid.shape}")
        usable &= valid[:, None] if valid.ndim == 1 else valid
    usable &= bool(config.dvl_updates)

    for name, x in (("mounting_rpy_deg", mounting_rpy_deg),
                    ("imu_position_body", imu_position_body),
                    ("dvl_position_body", dvl_position_body)):
        if np.shape(x) != (3,) or not np.isfinite(np.asarray(x, dtype=float)).all():
            raise ValueError(f"{name}: expected 3 finite numbers, got {x!r}")
    rotation = np.asarray(start.rotation, dtype=float)
    if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3),
                                                   atol=1e-6):
        raise ValueError("start.rotation: expected a 3 x 3 rotation matrix, body -> NED "
                         f"(rotation_rpy, or start_from_reference), got {rotation.tolist()}")
    # The start: IMU sample i0 at or just before start.time; the IMU point's state.
    i0 = max(int(np.searchsorted(t, start.time, side="right")) - 1, 0)
    r_imu = np.asarray(imu_position_body, dtype=float)
    r_dvl = np.asarray(dvl_position_body, dtype=float)
    c0 = rotation
    p0 = np.asarray(start.position_ned, dtype=float) + c0 @ r_imu
    w0 = w[i0] if start.angular_rate is None else np.asarray(start.angular_rate, float)
    v0 = np.asarray(start.velocity_ned, dtype=float) + c0 @ np.cross(w0, r_imu)
    if ping_row is None:
        ping_row = nearest_samples(t, tp)
    ping_row = np.asarray(ping_row, dtype=np.int64)
    if ping_row.shape != tp.shape or ((ping_row < 0) | (ping_row >= len(t))).any():
        raise ValueError(f"ping_row: expected ({len(tp)},) IMU sample indices in [0, "
                         f"{len(t)}), one per ping, got shape {ping_row.shape}")
    ping_row = ping_row - i0
    ping_row[ping_row < 0] = -1
    if ping_row.size and (np.diff(ping_row) < 0).any():
        raise ValueError("dvl_time: expected increasing times")

    cfg = config
    if cfg.latitude_deg is not None:
        latitude_deg = cfg.latitude_deg
    earth = (cfg.earth_rate if cfg.earth_rate is not None else latitude_deg is not None)
    if earth and latitude_deg is None:
        raise ValueError("latitude_deg: the Earth's rate needs the latitude")
    if latitude_deg is not None and not -90.0 <= float(latitude_deg) <= 90.0:
        raise ValueError(f"latitude_deg: expected deg in [-90, 90], got {latitude_deg!r}")
    omega_ie = earth_rate_ned(latitude_deg) if earth else np.zeros(3)
    g = (cfg.gravity if cfg.gravity is not None else gravity if gravity is not None
         else normal_gravity(latitude_deg, height_m) if latitude_deg is not None else None)
    if g is None:
        raise ValueError("gravity: expected it, or latitude_deg for the normal gravity")
    if not 0.0 < g < 100.0:  # NaN too; 9.78-9.83 on the Earth
        raise ValueError(f"gravity: expected its magnitude in m/s^2 (positive: down is the "
                         f"NED frame's +z), got {g!r}")
    force = force_slip(f, g)
    if force is not None:
        raise ValueError(f"specific_force: its median magnitude is {force:.4g} m/s^2; "
                         f"expected about g, {g:.4g} m/s^2 (in g? multiply by 9.80665 first)")
    # On the Earth, g is the gravity at the frame's origin and grows with the depth below
    # it as the normal gravity's free-air term does (3.1e-6 m/s^2 per m), as auvsim's
    # IMU reads it; in the flat world it is the same everywhere.
    g_grad = (normal_gravity(latitude_deg, height_m - 1.0)
              - normal_gravity(latitude_deg, height_m)) if earth else 0.0
    beam_states = cfg.beam_states if cfg.beam_states is not None else True
    nb = N_BEAM if beam_states else N_CORE
    ins = instrument
    scale_std = (ins.gyro_scale_factor_std if cfg.gyro_scale_factor_std is None
                 else cfg.gyro_scale_factor_std)
    cross_std = (ins.gyro_misalignment_std if cfg.gyro_misalignment_std is None
                 else cfg.gyro_misalignment_std)
    stated = scale_std > 0 or cross_std > 0
    gyro_matrix = cfg.gyro_matrix_states if cfg.gyro_matrix_states is not None else stated
    if gyro_matrix and not stated:
        raise SettingsError("gyro_matrix_states: expected gyro_scale_factor_std or "
                            "gyro_misalignment_std above 0 in the settings: its IMU states "
                            "no gyro scale factor or misalignment")
    # The DVL's slow error as a velocity error of its frame (3 states, as a simulated DVL
    # makes it and a real one's velocity shows it) where the beams are measured; on a
    # velocity the per-axis biases c_k are the same thing.
    slow = (cfg.slow_error_states if cfg.slow_error_states is not None
            else beams is not None and beam_states and ins.slow_error_std > 0)
    if slow and not (beam_states and ins.slow_error_std > 0):
        raise SettingsError("slow_error_states needs a DVL slow error and beam_states; "
                            "expected an instrument with slow_error_std above 0 and "
                            "beam_states not false")
    si = nb if slow else -1
    n = nb + (N_SLOW if slow else 0) + (N_GYRO_MATRIX if gyro_matrix else 0)
    gi = n - N_GYRO_MATRIX if gyro_matrix else -1
    std = np.concatenate([
        np.asarray(start.position_std, dtype=float), np.asarray(start.velocity_std, float),
        np.asarray(start.attitude_std, dtype=float),
        np.full(3, ins.accel_bias_std if cfg.accel_bias_std is None else cfg.accel_bias_std),
        np.full(3, ins.gyro_bias_std if cfg.gyro_bias_std is None else cfg.gyro_bias_std),
        np.full(4, cfg.beam_scale_std), np.full(4, cfg.beam_bias_std),
        np.radians(_known(cfg.misalignment_std_deg, mounting_std_deg, MISALIGNMENT_STD_DEG)),
        _known(cfg.lever_arm_std, dvl_position_std, LEVER_ARM_STD)])[:nb]
    if slow:
        std = np.concatenate([std, np.full(N_SLOW, ins.slow_error_std)])
    if gyro_matrix:  # K_g: scale factors on its diagonal, misalignments off it
        std = np.concatenate([std, np.where(np.eye(3).ravel() > 0, scale_std, cross_std)])
    P = np.diag(std**2)
    common = ins.common_scale_std if cfg.common_scale_std is None else cfg.common_scale_std
    if beam_states and common > 0:  # the scale factors' shared part: a correlated prior
        P[15:19, 15:19] += common**2
    q = np.array([
        (ins.accel_noise_density if cfg.accel_noise_density is None
         else cfg.accel_noise_density) ** 2,
        (ins.gyro_noise_density if cfg.gyro_noise_density is None
         else cfg.gyro_noise_density) ** 2,
        ins.accel_bias_psd if cfg.accel_bias_psd is None else cfg.accel_bias_psd,
        ins.gyro_bias_psd if cfg.gyro_bias_psd is None else cfg.gyro_bias_psd]
    ) * cfg.process_noise_scale**2
    k = 4 if beams is not None else 3
    for name in ("measurement_std", "noise_growth"):
        given = np.shape(getattr(ins, name))
        if given not in ((), (1,), (k,)):
            raise ValueError(f"instrument.{name}: expected one number or ({k},), one per "
                             f"{'beam' if k == 4 else 'velocity axis'} (the filter is given "
                             f"{'beams' if k == 4 else 'a velocity'}); got shape {given}")
    white, growth = _measurement_std(cfg, ins.measurement_std, ins.noise_growth,
                                     beams=beams is not None, beam_angle_deg=beam_angle_deg)
    r_meas = (white * cfg.noise_scale) ** 2
    r_growth = growth * cfg.noise_scale
    if not np.isfinite(r_meas).all():
        raise ValueError("instrument.measurement_std: expected finite stds, or "
                         "beam_noise_std / velocity_noise_std in config; got "
                         f"{ins.measurement_std!r}")
    dt = np.concatenate([[0.0], np.diff(t[i0:])])
    # The measurement biases c_k: constant (``beam_bias_std``), or first-order Gauss-Markov
    # with the instrument's slow error (its std added, its correlation time) or
    # ``bias_time``. The constant part it lets decay is a small share of its variance
    # (1 mm/s beside the real Navigator's 9 mm/s: 1.2 %).
    bias_time = cfg.bias_time if cfg.bias_time is not None else (
        ins.slow_error_time if ins.slow_error_std > 0 else None)
    bias_std = math.hypot(cfg.beam_bias_std, ins.slow_error_std)
    if slow:  # the slow error in e; the biases c_k constant at beam_bias_std
        bias_std = ins.slow_error_std
    elif bias_time is not None and beam_states:
        P[19:23, 19:23] = np.diag(np.full(4, bias_std**2))
    decay = 0.0 if bias_time is None else 1.0 / bias_time
    floor, ceiling = cfg.adaptive_range
    if cfg.adaptive == "learned" and noise_model is None:
        from beamsnet.estimators.noisemodel import load_noise_model

        if cfg.noise_model is None:
            raise DataError("FilterConfig.noise_model: expected the learned noise model's "
                            "file with adaptive = \"learned\" (beamsnet reproduce adaptive "
                            "writes one)")
        noise_model = load_noise_model(cfg.noise_model)
    net = (noise_model.arrays() if cfg.adaptive == "learned" and noise_model is not None
           else _NO_NET)
    if cfg.adaptive == "learned":
        floor, ceiling = noise_model.bounds
    # A signal that comes while the loop runs is handled as it hands back its arrays,
    # inside numba's unpickling, where a KeyboardInterrupt became a chain of SystemErrors
    # or a segmentation fault: held until it has returned, then raised here.
    with interrupts_held():
        (out_v, cov, pos, x, sd, used, rejected, reset, rot, r_used, features, innovations,
         hph, scale, stated_std, innovation_var) = _filter(
            f[i0:], w[i0:], dt, float(g), float(g_grad), omega_ie, imu_samples == "interval",
            ping_row, np.nan_to_num(meas),
            np.ascontiguousarray(usable), np.ascontiguousarray(dirs, dtype=float),
            rotation_rpy(*np.radians(mounting_rpy_deg)), r_dvl - r_imu, r_imu, p0.copy(),
            v0.copy(), c0.copy(), np.zeros(3), np.zeros(3), np.zeros((3, 3)), P, q,
            np.ascontiguousarray(r_meas), np.ascontiguousarray(r_growth, dtype=float),
            chi2_1dof(cfg.gate_probability), n, si, gi, decay,
            2.0 * bias_std**2 * decay,
            cfg.watch_pings, float(cfg.watch_share), _parity(dirs),
            _clock_setting(cfg) if timing_std is None else float(timing_std),
            cfg.adaptive_window if cfg.adaptive == "innovation" else 0,
            float(floor**2), float(ceiling**2),
            _gated_variance_share(cfg.gate_probability), *net)
    nees = np.full(len(tp), np.nan)
    if truth_velocity_dvl is not None:
        err = out_v - np.asarray(truth_velocity_dvl, dtype=float)
        ok = np.isfinite(err).all(axis=1)
        nees[ok] = np.einsum("pi,pi->p", err[ok],
                             np.linalg.solve(cov[ok], err[ok][..., None])[..., 0])
    events = tuple(Event(int(k), float(tp[k]), "restart",
                         f"ping {k} at {tp[k]:.2f} s: the gate had rejected at least "
                         f"{100 * cfg.watch_share:.0f} % of the last {cfg.watch_pings} pings' "
                         "measurements; velocity restarted from the measurements, attitude "
                         "and position widened")
                   for k in np.flatnonzero(reset))
    return FilterTrack(ping_time=tp, velocity_dvl=out_v,
                       velocity_std=np.sqrt(np.diagonal(cov, axis1=1, axis2=2)),
                       velocity_cov=cov, position_ned=pos,
                       position_std=sd[:, _STATES["position"]],
                       **{name: x[:, _STATES[name]] for name in _INSTRUMENT_STATES},
                       **{f"{name}_std": sd[:, _STATES[name]] for name in _INSTRUMENT_STATES},
                       beams_used=used, beams_rejected=rejected, nees_velocity=nees,
                       accepted=used > 0, events=events, rotation=rot,
                       measurement_std=np.sqrt(r_used), features=features,
                       innovation=innovations, innovation_hph=hph,
                       innovation_var=innovation_var, stated_std=stated_std,
                       noise_scale=scale, noise=Instrument(
                           accel_noise_density=math.sqrt(q[0]),
                           gyro_noise_density=math.sqrt(q[1]), accel_bias_std=float(std[9]),
                           gyro_bias_std=float(std[12]), accel_bias_psd=float(q[2]),
                           gyro_bias_psd=float(q[3]),
                           measurement_std=np.sqrt(r_meas), noise_growth=r_growth,
                           slow_error_std=ins.slow_error_std,
                           slow_error_time=bias_time, common_scale_std=common,
                           gyro_scale_factor_std=scale_std,
                           gyro_misalignment_std=cross_std))


def _measurement_std(cfg: FilterConfig, stated, growth=0.0, *, beams: bool,
                     beam_angle_deg: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(K,) m/s, each measurement's white noise at rest, and (K,) m/s per m/s, its growth
    with the speed: a setting wins, constant (a beam's ``beam_noise_std``, at least
    ``BEAM_NOISE_FLOOR``; a velocity axis's ``velocity_noise_std``, else
    ``beam_noise_std`` through the Janus geometry where the beams' angle is known), else
    ``stated`` and ``growth``, the instrument's (NaN where it states none)."""
    k = 4 if beams else 3
    if beams and cfg.beam_noise_std is not None:
        std = np.full(4, max(float(cfg.beam_noise_std), BEAM_NOISE_FLOOR))
    elif not beams and cfg.velocity_noise_std is not None:
        std = np.full(3, float(cfg.velocity_noise_std))
    elif not beams and cfg.beam_noise_std is not None and beam_angle_deg is not None:
        std = np.maximum(janus_velocity_std(float(cfg.beam_noise_std), beam_angle_deg),
                         BEAM_NOISE_FLOOR)
    else:
        return (np.broadcast_to(np.asarray(stated, dtype=float), (k,)),
                np.broadcast_to(np.asarray(growth, dtype=float), (k,)))
    return std, np.zeros(k)


def _known(setting: float | None, calibrated, default: float) -> np.ndarray:
    """(3,) std: the setting where given, else the calibration's, else the default."""
    if setting is not None:
        return np.full(3, float(setting))
    if calibrated is not None:
        return np.asarray(calibrated, dtype=float).reshape(3)
    return np.full(3, default)


def run_mission(mission, config: FilterConfig = FilterConfig(), *,
                beam_correction: tuple[np.ndarray, np.ndarray] | None = None,
                noise_model=None, measurements: str = "auto") -> FilterTrack:
    """Run the filter over one mission (``run_arrays`` on its streams).

    A simulated mission starts at its truth (or, with ``initial_error_seed``, drawn
    around it); a recorded one at its reference's first sample within the IMU's span
    (``start_from_reference``). The instrument's noise comes from the mission's
    attributes; the Earth rotates when it has a latitude.

    Args:
        mission: an ``auvsim.data.reader.Mission`` with an IMU (simulated or recorded).
        config: the filter's settings.
        beam_correction: per-beam (scale factors s, biases b (m/s)), each (4,), known from
            a calibration (``beamsnet.estimators.baselines.BeamCalibration``): every beam is
            used as ``(y - b) / (1 + s)``. None: the beams as measured.
        noise_model: a learned noise model, for ``config.adaptive = "learned"``
            (``run_arrays``).
        measurements: ``"auto"``: the beams where the file has measured ones, else the
            DVL's velocity; ``"velocity"``: the DVL's velocity (its LS solution on a
            simulated file) even where beams are measured.

    Returns:
        The track at every DVL ping.

    Raises:
        NoImuError: the mission has no IMU record (an imported stream).
        DataError: settings asking for states this file's instrument gives nothing to hold
            (``SettingsError``, with the mission's name); a recorded mission without a
            reference attitude to start from and no ``start_heading_deg`` in ``config``
            (``_aligned_start``'s one line).
    """
    if not mission.has("imu"):
        raise NoImuError(f"mission {mission.name} has no IMU record; the INS/DVL filter "
                         "integrates the IMU, so it is skipped")
    a, cfg = mission.attrs, config
    recorded = mission.origin == "recorded"
    imu, dvl = mission.imu, mission.dvl
    f = np.asarray(imu.specific_force, dtype=float)
    w = np.asarray(imu.angular_rate, dtype=float)
    imu_time = np.asarray(imu.time if "time" in imu else mission.truth.time, dtype=float)
    rate = float(a["imu_rate_hz"]) if "imu_rate_hz" in a else 1.0 / float(
        np.median(np.diff(imu_time)))
    r_imu = np.asarray(a.get("imu_position_body", np.zeros(3)), dtype=float)
    latitude = None if a.get("latitude_deg") is None else float(a["latitude_deg"])

    if recorded:
        start_clock, timing_std = clock_stds(a, cfg, rate)
        if mission.has("reference") and "quaternion" in mission.reference:
            start = _reference_start(mission, imu_time, w, cfg, start_clock)
        else:
            start = _aligned_start(mission, imu_time, f, w, cfg)
    else:
        start = _truth_start(mission, r_imu, cfg)

    config_of = _dataset_config(mission)  # a simulated file's config ({} otherwise)
    imu_cfg, dvl_cfg = config_of.get("imu", {}), config_of.get("dvl", {})

    def bias_std(turn_on_key, instability_key):
        # A simulated file stores its turn-on biases as drawn (the truth), their spread
        # only in its config; a recorded log's attributes give the instability alone.
        turn_on = 0.0 if recorded else float(imu_cfg.get(turn_on_key, 0.0))
        return math.hypot(turn_on, float(a[instability_key]))

    def psd(instability_key, tau_key):
        sigma = float(a[instability_key])
        tau = float(a.get(tau_key, a["imu_bias_correlation_time"]))
        return 2.0 * sigma**2 / tau

    def density(key, samples):
        spec = float(a[key])
        if not recorded:
            return spec
        return math.hypot(spec, quantisation_density(samples, rate))

    beam_angle = float(a["beam_angle_deg"]) if "beam_angle_deg" in a else None
    beam_noise = float(a["dvl_noise_std"]) if "dvl_noise_std" in a else None
    if measurements not in ("auto", "velocity"):
        raise ValueError(f"measurements: expected 'auto' or 'velocity', got {measurements!r}")
    use_beams = "beam_velocity" in dvl and not (
        recorded and a.get("dvl_beams_derived", False)) and measurements == "auto"
    # The instrument's noise as the file states it (NaN where it does not); run_arrays
    # applies the settings.
    # A simulated instrument's beam noise grows with the speed (its config's
    # ``noise_speed_coeff``; the range term is not modelled here).
    growth = 0.0 if recorded else float(
        dvl_cfg.get("noise_speed_coeff", 0.0))
    if use_beams:
        measurement_std = np.full(4, math.nan if beam_noise is None
                                  else max(beam_noise, BEAM_NOISE_FLOOR))
        noise_growth = np.full(4, growth)
    elif beam_noise is not None and beam_angle is not None:
        measurement_std = np.maximum(janus_velocity_std(beam_noise, beam_angle),
                                     BEAM_NOISE_FLOOR)
        noise_growth = janus_velocity_std(growth, beam_angle)
    else:
        measurement_std = np.full(3, float(a.get("dvl_velocity_accuracy", math.nan)))
        noise_growth = np.zeros(3)
    white = _measurement_std(cfg, measurement_std, beams=use_beams,
                             beam_angle_deg=beam_angle)[0]
    if not np.isfinite(white).all():
        stated, setting = (("dvl_noise_std", "beam_noise_std") if use_beams else
                           ("dvl_noise_std or dvl_velocity_accuracy", "velocity_noise_std"))
        raise DataError(f"mission {mission.name}: no DVL noise ({stated}); expected it, or "
                        f"{setting} in the filter's settings")
    slow_std, slow_time = _slow_error(a, recorded=recorded)
    instrument = Instrument(
        accel_noise_density=density("imu_accel_noise_density", f),
        gyro_noise_density=density("imu_gyro_noise_density", w),
        accel_bias_std=bias_std("accel_turn_on_bias", "imu_accel_bias_instability"),
        gyro_bias_std=bias_std("gyro_turn_on_bias", "imu_gyro_bias_instability"),
        accel_bias_psd=psd("imu_accel_bias_instability", "imu_accel_bias_correlation_time"),
        gyro_bias_psd=psd("imu_gyro_bias_instability", "imu_gyro_bias_correlation_time"),
        measurement_std=measurement_std, noise_growth=noise_growth, slow_error_std=slow_std,
        slow_error_time=slow_time,
        # A simulated file's gyro scale factors and misalignments are drawn (its
        # attributes) from the spreads of its config; a recorded log states none.
        gyro_scale_factor_std=float(imu_cfg.get("gyro_scale_factor_std", 0.0)),
        common_scale_std=0.0 if recorded else float(
            dvl_cfg.get("sound_speed_std", 0.0)),
        gyro_misalignment_std=float(imu_cfg.get("gyro_misalignment_std", 0.0)))

    dvl_time = np.asarray(dvl.time, dtype=float)
    if use_beams:
        beams = np.asarray(dvl.beam_velocity, dtype=float)
        if beam_correction is not None:
            scale, bias = (np.asarray(x, dtype=float) for x in beam_correction)
            beams = (beams - bias) / (1.0 + scale)
        mode = dvl.mode if "mode" in dvl else np.zeros(len(beams), dtype=np.int64)
        # A beam with bottom lock measures the velocity over ground whether or not the
        # ping has the 3 such beams an LS velocity needs (mode 0 or -1; ``valid`` is the
        # lock there); in water track (mode 1) ``valid`` means it measured the water.
        valid = np.asarray(dvl.valid, dtype=bool) & (np.asarray(mode) != 1)[:, None]
        measured = dict(beams=beams)
    else:
        velocity = np.asarray(dvl.velocity_ls if "velocity_ls" in dvl else dvl.velocity,
                              dtype=float)
        valid = (np.asarray(dvl.mode) == 0) if "mode" in dvl else None
        measured = dict(velocity=velocity)
    truth_v = None if recorded or "velocity" not in dvl else np.asarray(dvl.velocity, float)
    ping_row = (np.asarray(imu.index_of_dvl, dtype=np.int64) if "index_of_dvl" in imu
                else None)
    # A file that states a slow DVL error needs the bias states to hold it.
    beam_states = cfg.beam_states if cfg.beam_states is not None else (recorded or slow_std > 0)
    mounting_std, position_std = applied_dvl_errors(a)
    drawn = float(dvl_cfg.get("misalignment_std_deg", 0.0))
    if mounting_std is None and not recorded and drawn > 0:
        # A simulated DVL's mounting is drawn around the nominal with this spread.
        mounting_std = np.full(3, drawn)
    try:
        return run_arrays(
            imu_time, f, w, dvl_time, **measured, valid=valid, beam_angle_deg=beam_angle,
            mounting_rpy_deg=np.asarray(a.get("dvl_mounting_rpy_deg", np.zeros(3)), float),
            imu_position_body=r_imu,
            dvl_position_body=np.asarray(a.get("dvl_position_body", np.zeros(3)), float),
            start=start, instrument=instrument, latitude_deg=latitude,
            height_m=float(a.get("height_m", 0.0)), gravity=mission.gravity,
            config=dataclasses.replace(cfg, beam_states=beam_states),
            truth_velocity_dvl=truth_v, ping_row=ping_row,
            timing_std=timing_std if recorded else 0.0, mounting_std_deg=mounting_std,
            dvl_position_std=position_std, noise_model=noise_model,
            imu_samples="interval" if recorded else "held")
    except SettingsError as e:  # the filter's settings against this file's instrument
        raise DataError(f"mission {mission.name}: {e} (the filter's settings, "
                        "--filter-config)") from None


def _slow_error(a: dict, *, recorded: bool) -> tuple[float, float | None]:
    """The DVL's time-correlated velocity error (std per axis, m/s; correlation time, s):
    a file's own (``dvl_slow_error_std``, ``_time``); for a recorded log that states none,
    the slow error measured on a real Teledyne RDI Navigator
    (``auvsim.data.checklog.slow_error``); for a simulated file that states none, none."""
    if not recorded and float(a.get("dvl_slow_error_std", 0.0)) <= 0:
        return 0.0, None
    return slow_error(a)


def _truth_start(mission, r_imu: np.ndarray, cfg: FilterConfig) -> Start:
    """A simulated mission's start: its truth at sample 0, or drawn around it."""
    truth = mission.truth
    c0 = rotation_matrices(truth.quaternion[:1])[0]
    p0 = np.asarray(truth.position_ned[0], dtype=float)
    v0 = np.asarray(truth.velocity_ned[0], dtype=float)
    level, heading = np.radians(cfg.attitude_std_deg)
    att_std = np.array([level, level, heading])
    if cfg.initial_error_seed is not None:
        rng = np.random.default_rng(cfg.initial_error_seed)
        # Drawn for the IMU point, as before the array API: the same draws.
        w0 = np.asarray(truth.angular_rate[0], dtype=float)
        p_imu = p0 + c0 @ r_imu + cfg.position_std * rng.standard_normal(3)
        v_imu = v0 + c0 @ np.cross(w0, r_imu) + cfg.velocity_std * rng.standard_normal(3)
        c0 = _exp(att_std * rng.standard_normal(3)) @ c0
        p0 = p_imu - c0 @ r_imu
        v0 = v_imu - c0 @ np.cross(w0, r_imu)
    return Start(time=float(truth.time[0]), position_ned=p0, velocity_ned=v0, rotation=c0,
                 position_std=np.full(3, cfg.position_std),
                 velocity_std=np.full(3, cfg.velocity_std), attitude_std=att_std,
                 angular_rate=np.asarray(truth.angular_rate[0], dtype=float))


def _clock_setting(cfg: FilterConfig) -> float:
    """s, the clock uncertainty the settings give: ``clock_std``, else ``CLOCK_STD``."""
    return CLOCK_STD if cfg.clock_std is None else cfg.clock_std


def clock_stds(attrs, cfg: FilterConfig, imu_rate_hz: float) -> tuple[float, float]:
    """How uncertain a recorded file's clocks are, s: (the IMU's against the reference's,
    for a start from it; a ping's on the IMU's clock). ``cfg.clock_std`` for both where
    set; else how well ``auvsim check-log --apply`` knew the offsets it applied
    (``applied_clock_errors``; a ping's from both, each found against the reference),
    the IMU's with what a log leaves open of its stamps besides (which instant of a
    sample's interval a stamp marks: uniform over one sample at ``imu_rate_hz``,
    1 / (rate sqrt 12)), and ``CLOCK_STD`` for a clock it did not find; ``CLOCK_STD`` for
    both where it found neither (a log it did not correct). A clock rate check-log found
    insignificant, and so did not apply, is taken as none."""
    if cfg.clock_std is not None:
        return cfg.clock_std, cfg.clock_std
    imu, dvl = applied_clock_errors(attrs)
    if imu is None and dvl is None:
        return CLOCK_STD, CLOCK_STD
    imu = CLOCK_STD if imu is None else math.hypot(imu, 1.0 / (imu_rate_hz * math.sqrt(12)))
    return imu, math.hypot(imu, CLOCK_STD if dvl is None else dvl)


def _reference_start(mission, imu_time: np.ndarray, w: np.ndarray,
                     cfg: FilterConfig, clock_std: float) -> Start:
    """A recorded mission's start: its reference's first sample within the IMU's span,
    uncertain by what the vehicle does in ``clock_std`` s besides."""
    quaternion = require_attitude(mission)
    ref = mission.reference
    t = np.asarray(ref.time, dtype=float)
    k = int(np.searchsorted(t, imu_time[0]))
    if k >= len(t):
        raise DataError(f"mission {mission.name}: its reference ends before the IMU starts")
    i = min(int(np.searchsorted(imu_time, t[k])), len(imu_time) - 1)
    c = rotation_matrices(np.asarray(quaternion[k:k + 1], dtype=float))[0]
    v = np.asarray(ref.velocity_ned, dtype=float)
    accel = (v[min(k + 1, len(t) - 1)] - v[max(k - 1, 0)]) / max(
        t[min(k + 1, len(t) - 1)] - t[max(k - 1, 0)], 1e-9)
    return start_from_reference(imu_time[i], np.asarray(ref.position_ned[k], dtype=float),
                                v[k], c, angular_rate=w[i], acceleration=accel, config=cfg,
                                clock_std=clock_std)


def _aligned_start(mission, imu_time: np.ndarray, f: np.ndarray, w: np.ndarray,
                   cfg: FilterConfig) -> Start:
    """A recorded mission's start where its log has no reference attitude: a coarse
    alignment on the heading the settings give (``start_heading_deg``), less the
    acceleration the DVL shows over its window (``dvl_acceleration``), at the
    reference's first position and velocity within the IMU's span where the log has a
    reference, else at the local origin with the first DVL velocity turned to NED (the
    DVL's mounting; its lever arm's share left to the start's 0.5 m/s).

    Raises:
        DataError: no heading is given, in one line saying where to give it.
    """
    if cfg.start_heading_deg is None:
        what = ("its reference has no attitude" if mission.has("reference")
                else "it has no reference")
        raise DataError(f"mission {mission.name}: {what} to start the filter from; expected "
                        "start_heading_deg (and start_heading_std_deg) in the filter's "
                        "settings (--filter-config), for a start levelled from the "
                        "accelerometers, or a reference with roll, pitch and yaw")
    dvl = mission.dvl
    velocity = np.asarray(dvl.velocity_ls, dtype=float)
    mounting = rotation_rpy(*np.radians(np.asarray(
        mission.attrs.get("dvl_mounting_rpy_deg", np.zeros(3)), dtype=float)))
    heading = dict(heading_deg=cfg.start_heading_deg,
                   heading_std_deg=cfg.start_heading_std_deg,
                   acceleration_body=dvl_acceleration(dvl.time, velocity, mounting, imu_time,
                                                      w))
    if mission.has("reference"):
        ref = mission.reference
        t = np.asarray(ref.time, dtype=float)
        k = int(np.searchsorted(t, imu_time[0]))
        if k >= len(t):
            raise DataError(f"mission {mission.name}: its reference ends before the IMU "
                            "starts")
        return coarse_alignment(imu_time, f, **heading,
                                position_ned=np.asarray(ref.position_ned[k], float),
                                velocity_ned=np.asarray(ref.velocity_ned[k], float),
                                position_std=cfg.position_std, speed_std=cfg.velocity_std)
    level = coarse_alignment(imu_time, f, **heading)
    first = np.flatnonzero(np.isfinite(velocity).all(axis=1))
    if len(first) == 0:
        return level
    return level._replace(velocity_ned=level.rotation @ mounting @ velocity[first[0]])


def _parity(dirs: np.ndarray) -> np.ndarray:
    """The unit vector a with a^T ``dirs`` = 0 for four directions of rank 3 (a Janus
    DVL's beams: the combination its error velocity is made of), else zeros (three beams or
    a velocity's axes: no redundancy to check)."""
    dirs = np.asarray(dirs, dtype=float)
    if dirs.shape[0] != 4 or np.linalg.matrix_rank(dirs) != 3:
        return np.zeros(dirs.shape[0])
    return np.ascontiguousarray(np.linalg.svd(dirs)[0][:, 3])


def _gated_variance_share(probability: float) -> float:
    """kappa = E[min(nu^2, c^2 S)] / S for a normal innovation nu of variance S and the
    gate c^2 = ``chi2_1dof(probability)``: the second moment of a standard normal
    winsorised at +-c, integrated by parts, (2 Phi(c) - 1) - 2 c phi(c) + 2 c^2 (1 - Phi(c));
    0.998 at the default gate."""
    normal = statistics.NormalDist()
    c = math.sqrt(chi2_1dof(probability))
    tail = 1.0 - normal.cdf(c)
    return (1.0 - 2.0 * tail) - 2.0 * c * normal.pdf(c) + 2.0 * c * c * tail


def chi2_quantile(dof: int, probability: float) -> float:
    """Quantile of chi-square with ``dof`` degrees of freedom, by Wilson and Hilferty's
    cube-root normal approximation (1931): dof (1 - 2/(9 dof) + z sqrt(2/(9 dof)))^3, z the
    normal's quantile; within 1 % of the exact from 10 dof at 0.999 (the tests check it
    against scipy's)."""
    z = statistics.NormalDist().inv_cdf(probability)
    a = 2.0 / (9.0 * dof)
    return dof * (1.0 - a + z * math.sqrt(a)) ** 3


CONSISTENCY_PINGS = 10  # pings per window of the innovations' consistency test
CONSISTENCY_PROBABILITY = 0.999  # a window beyond this chi-square quantile is flagged


def innovation_consistency(track: FilterTrack, window: int = CONSISTENCY_PINGS,
                           probability: float = CONSISTENCY_PROBABILITY) -> dict:
    """Whether the filter's innovations are as large as it predicts, as one can ask of a
    log without a reference: every offered measurement's normalised innovation
    nu^2 / S (``innovation``, ``innovation_var``: what the gate saw), and their sums over
    consecutive windows of ``window`` pings, each chi-square with as many degrees of
    freedom as measurements where the filter's model holds (Bar-Shalom, Li and
    Kirubarajan 2001, sec. 5.4: the NIS test). Returns ``mean_nis`` (1 where the
    covariance is right; NaN without innovations), ``gated_nis`` (the mean of each NIS
    capped at the default gate's chi-square quantile, over what that cap keeps of a
    consistent filter's, ``_gated_variance_share``: 1 where the covariance is right too,
    and an outlier the gate rejected moves it by at most the gate over the count, where
    one of 0.3 m/s takes the plain mean to a hundred), ``windows``, ``windows_above``
    (sums beyond their ``probability`` quantile) and ``worst_time`` (s, the first ping of
    the window furthest beyond it; NaN if none is)."""
    nis = (np.asarray(track.innovation, dtype=float) ** 2
           / np.asarray(track.innovation_var, dtype=float))
    offered = np.isfinite(nis)
    gate = chi2_1dof(FilterConfig.gate_probability)
    capped = np.minimum(nis[offered], gate)
    out = dict(mean_nis=float(nis[offered].mean()) if offered.any() else math.nan,
               gated_nis=(float(capped.mean()) / _gated_variance_share(
                   FilterConfig.gate_probability) if offered.any() else math.nan),
               windows=0, windows_above=0, worst_time=math.nan)
    worst = 1.0
    for start in range(0, len(nis) - window + 1, window):
        part = nis[start:start + window]
        m = int(np.isfinite(part).sum())
        if m == 0:
            continue
        out["windows"] += 1
        ratio = float(np.nansum(part)) / chi2_quantile(m, probability)
        if ratio > 1.0:
            out["windows_above"] += 1
            if ratio > worst:
                worst, out["worst_time"] = ratio, float(track.ping_time[start])
    return out


def chi2_1dof(probability: float) -> float:
    """Quantile of chi-square with 1 dof: the square of the normal's two-sided one."""
    return statistics.NormalDist().inv_cdf(0.5 + 0.5 * probability) ** 2


def run(path, mission_name: str, config: FilterConfig = FilterConfig()) -> FilterTrack:
    """``run_mission`` on mission ``mission_name`` of the dataset at ``path``."""
    try:
        f = open_dataset(path)
    except DatasetError as e:  # the dataset module's own one-line message
        raise DataError(str(e)) from None
    with f:
        if mission_name not in f.missions:
            raise DataError(f"mission_name: {mission_name!r} not in {path}; it has "
                            f"{', '.join(f.missions)}")
        return run_mission(f.missions[mission_name], config)


class InsDvlFilter:
    """The filter as a beamsnet estimator: ``fit`` learns the DVL's per-beam scale factors
    and biases on the training split (``BeamCalibration``: the systematic beam errors of
    eq. 7, which the IMU cannot tell from the velocity on a steady leg, as every other
    calibrated estimator of the tables learns them), ``predict`` runs each mission of the
    windows from its start (causal) on the corrected beams and returns the posterior
    DVL-frame velocity at each sample's ping, ``positions`` its position. Tracks are cached
    per mission until the next ``fit``. A mission without an IMU raises ``NoImuError``
    (from ``tracks`` and ``predict``)."""

    name = "INS/DVL"

    def __init__(self, dataset, config: FilterConfig | None = None, *,
                 calibrate: bool = True) -> None:
        """Args: dataset: path of the file the windows come from; config: settings;
        calibrate: correct the beams by the calibration ``fit`` learns (False: the beams
        as measured, ``fit`` learns nothing)."""
        self.dataset = dataset
        self.config = config if config is not None else FilterConfig()
        self.calibrate = calibrate
        if not calibrate:
            self.name = "INS/DVL (raw beams)"
        self.correction: tuple[np.ndarray, np.ndarray] | None = None
        self.noise_model = None  # a learned noise model (``adaptive = "learned"``)
        self._tracks: dict[str, FilterTrack] = {}

    def fit(self, train: Windows) -> InsDvlFilter:
        """Learn the beam calibration on ``train``; on a log without a reference
        (``NO_REFERENCE``: nothing to calibrate against) the beams stay as measured, and
        ``correction`` None says so."""
        self.correction = None
        if self.calibrate and train.reference != NO_REFERENCE:
            calibration = BeamCalibration().fit(train)
            self.correction = (calibration.scale, calibration.bias)
        self._tracks = {}
        return self

    def tracks(self, windows: Windows) -> dict[str, FilterTrack]:
        """The track of every mission the windows use, by name (run once, cached)."""
        wanted = [windows.names[i] for i in np.unique(windows.mission)]
        missing = [name for name in wanted if name not in self._tracks]
        if missing:
            with open_dataset(self.dataset) as f:
                for name in missing:
                    self._tracks[name] = run_mission(f.missions[name], self.config,
                                                     beam_correction=self.correction,
                                                     noise_model=self.noise_model)
        return {name: self._tracks[name] for name in wanted}

    def predict(self, windows: Windows) -> np.ndarray:
        """(S, 3) DVL-frame velocity, m/s, at each sample's ping: the track of mission
        ``windows.names[windows.mission]`` at the ping whose time is ``windows.time``
        (NaN if no ping has that time)."""
        return at_pings(self.tracks(windows), windows, "velocity_dvl")

    def positions(self, windows: Windows) -> np.ndarray:
        """(S, 3) estimated NED position of the body origin, m, at each sample's ping."""
        return at_pings(self.tracks(windows), windows, "position_ned")


class AdaptiveInsDvlFilter(InsDvlFilter):
    """The model-based adaptive filter: ``InsDvlFilter`` with each measurement's noise
    estimated from its innovations (``adaptive = "innovation"``, the module docstring's
    "Adaptive measurement noise"), where the settings ask for the fixed one; their
    ``adaptive_window`` and ``adaptive_range`` apply."""

    name = "INS/DVL (adaptive)"

    def __init__(self, dataset, config: FilterConfig | None = None, *,
                 calibrate: bool = True) -> None:
        config = config if config is not None else FilterConfig()
        if config.adaptive == "none":
            config = dataclasses.replace(config, adaptive="innovation")
        super().__init__(dataset, config, calibrate=calibrate)
        if not calibrate:
            self.name = "INS/DVL (adaptive, raw beams)"


def at_pings(tracks: dict, windows: Windows, field: str) -> np.ndarray:
    """(S, ...) ``field`` (P, ...) of each mission's track at each sample's ping: the
    track ``tracks[windows.names[windows.mission]]`` (a ``FilterTrack``, or anything with
    ``ping_time`` and that field) at the ping whose time is ``windows.time`` (to 1e-9
    relative); NaN where no ping has that time."""
    shape = np.shape(getattr(next(iter(tracks.values())), field))[1:] if tracks else ()
    out = np.full((len(windows.time), *shape), np.nan)
    for i in np.unique(windows.mission):
        track = tracks[windows.names[i]]
        rows = np.flatnonzero(windows.mission == i)
        k = np.minimum(np.searchsorted(track.ping_time, windows.time[rows]),
                       len(track.ping_time) - 1)
        hit = np.abs(track.ping_time[k] - windows.time[rows]) <= 1e-9 * np.maximum(
            1.0, np.abs(windows.time[rows]))
        out[rows[hit]] = np.asarray(getattr(track, field))[k[hit]]
    return out


ESTIMATORS = (
    Spec("INS/DVL", "INS/DVL filter: the IMU integrated, updated by each locked beam",
         "filter", make=InsDvlFilter, order=10,
         needs=Needs(beams=0, imu=True, text="needs the IMU record"),
         why="its noise model is the file's, and it gates beams it finds inconsistent"),
    Spec("INS/DVL (adaptive)", "INS/DVL filter whose beam noise is estimated from its "
         "innovations (Mohamed & Schwarz 1999)", "filter", make=AdaptiveInsDvlFilter,
         order=11, needs=Needs(beams=0, imu=True, text="needs the IMU record"),
         why="its beam noise follows the innovations, so a state error the gate lets through "
             "(a turn the IMU model misses) reads as DVL noise and weakens the DVL"),
)
