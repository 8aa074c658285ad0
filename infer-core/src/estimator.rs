//! On-device state estimation for position-only sensing (the docs are on [`Estimator`]).
use core::f32::consts::TAU;

use nalgebra::{Matrix2, RowVector2, Vector2};

use crate::error::{Error, Result};

/// What one observation entry is to the estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Channel {
    /// A measured position: filtered.
    Position,
    /// A measured angle (rad): filtered, innovation and estimate wrapped to `[-pi, pi]`.
    Angle,
    /// Not measured: `scale` times the estimated derivative of the position or angle at
    /// observation index `of`.
    Rate {
        /// Index of the position or angle.
        of: usize,
        /// Rate per unit of that entry's time derivative.
        scale: f32,
    },
    /// Measured and passed through unfiltered (still range-checked; an invalid reading holds
    /// the last valid one).
    Direct,
}

impl Channel {
    /// Whether the sensors deliver this entry (everything but a [`Channel::Rate`]).
    pub fn is_measured(self) -> bool {
        !matches!(self, Channel::Rate { .. })
    }
}

/// Tuning and timing of the filters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorConfig {
    /// Control period, seconds (> 0).
    pub dt: f32,
    /// Std of the unmodelled acceleration over a step, units per second squared (> 0).
    pub accel_std: f32,
    /// Std of a reading's noise, including quantisation (>= 0).
    pub meas_std: f32,
    /// Readings with `|y| >= limit` are rejected (> 0; infinity disables the range check).
    pub limit: f32,
    /// Std of the rate when a filter starts (> 0).
    pub initial_rate_std: f32,
}

/// Smallest measurement variance used, so that a noise-free sensor keeps the gain finite.
pub const MIN_MEAS_VAR: f32 = 1e-10;

/// What a tick did with the readings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StepReport {
    /// Readings that were NaN, infinite or out of range and were replaced by the prediction
    /// (or the held value). Non-zero is a sensor fault.
    pub rejected: usize,
    /// Observation index of the first rejected reading.
    pub first_rejected: Option<usize>,
}

/// State of one measured channel.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Track {
    /// Position (or the held value of a direct channel) and rate.
    x: Vector2<f32>,
    /// Covariance of `x` (unused for a direct channel).
    p: Matrix2<f32>,
    /// Has had a valid reading.
    ready: bool,
}

const IDLE: Track = Track {
    x: Vector2::new(0.0, 0.0),
    p: Matrix2::new(0.0, 0.0, 0.0, 0.0),
    ready: false,
};

/// Wraps an angle to `[-pi, pi]`.
fn wrap(angle: f32) -> f32 {
    libm::remainderf(angle, TAU)
}

fn positive(value: f32) -> bool {
    value > 0.0 && !value.is_nan()
}

/// A bank of constant-velocity Kalman filters for up to `N` observation entries. Its size is
/// fixed at compile time; it allocates nothing.
///
/// On-device state estimation for position-only sensing: a constant-velocity Kalman filter
/// per measured position, in fixed-size `nalgebra` matrices (no heap).
///
/// A device that measures positions (encoders, a tracker) but whose policy was trained on
/// positions *and* velocities runs one `Estimator` between its sensors and
/// [`Policy::act`](crate::Policy::act). Each observation entry is a [`Channel`]: a measured
/// position or angle (filtered), the rate of one of them (estimated, never measured), or a
/// directly measured value (passed through). Every tick, each position's filter
///
/// 1. predicts with the constant-velocity model, state `x = [p, v]`:
///    `x <- F x`, `P <- F P F^T + Q`, with `F = [[1, dt], [0, 1]]` and
///    `Q = a^2 [[dt^4/3, dt^3/2], [dt^3/2, dt^2]]` (white acceleration noise of std
///    [`accel_std`](EstimatorConfig::accel_std) `= a` over the step);
/// 2. updates with the reading `y` if it is valid (finite and inside
///    `+-`[`limit`](EstimatorConfig::limit)): innovation `e = y - p` (wrapped to
///    `[-pi, pi]` for angles), `S = P00 + r^2`, `K = P[:, 0] / S`, `x <- x + K e`, and the
///    Joseph form `P <- (I - K H) P (I - K H)^T + K r^2 K^T` (`r` =
///    [`meas_std`](EstimatorConfig::meas_std));
/// 3. otherwise holds the prediction and reports the reading as rejected: an invalid
///    reading never reaches the observation.
///
/// The observation then gets `p` for a position, `scale * v` of the named position for a
/// rate, and the last valid reading for a direct channel. A channel's first valid reading
/// starts its filter at `[y, 0]` with `P = diag(r^2, initial_rate_std^2)`; until every
/// channel has had one, [`Estimator::step`](Estimator::step) returns [`Error::NotReady`] and the
/// observation is not written.
///
/// Everything is `f32` in a fixed order of operations: bit-exact and deterministic.
#[derive(Debug, Clone)]
pub struct Estimator<const N: usize> {
    channels: [Channel; N],
    tracks: [Track; N],
    len: usize,
    measured: usize,
    f: Matrix2<f32>,
    q: Matrix2<f32>,
    r: f32,
    limit: f32,
    initial_rate_var: f32,
}

impl<const N: usize> Estimator<N> {
    /// An estimator for an observation whose entry `i` is `channels[i]`.
    pub fn new(channels: &[Channel], config: EstimatorConfig) -> Result<Self> {
        if channels.is_empty() || channels.len() > N {
            return Err(Error::ChannelCount {
                found: channels.len(),
                capacity: N,
            });
        }
        for (index, channel) in channels.iter().enumerate() {
            if let Channel::Rate { of, scale } = *channel {
                let is_position =
                    matches!(channels.get(of), Some(Channel::Position | Channel::Angle));
                if !is_position || !scale.is_finite() {
                    return Err(Error::BadRate { index, of });
                }
            }
        }
        let EstimatorConfig {
            dt,
            accel_std,
            meas_std,
            limit,
            initial_rate_std,
        } = config;
        let checks = [
            ("dt", positive(dt) && dt.is_finite()),
            ("accel_std", positive(accel_std) && accel_std.is_finite()),
            ("meas_std", meas_std >= 0.0 && meas_std.is_finite()),
            ("limit", positive(limit)),
            (
                "initial_rate_std",
                positive(initial_rate_std) && initial_rate_std.is_finite(),
            ),
        ];
        if let Some((field, _)) = checks.iter().find(|(_, ok)| !ok) {
            return Err(Error::BadConfig { field });
        }
        let a2 = accel_std * accel_std;
        let (dt2, dt3) = (dt * dt, dt * dt * dt);
        let mut all = [Channel::Direct; N];
        all[..channels.len()].copy_from_slice(channels);
        Ok(Self {
            channels: all,
            tracks: [IDLE; N],
            len: channels.len(),
            measured: channels.iter().filter(|c| c.is_measured()).count(),
            f: Matrix2::new(1.0, dt, 0.0, 1.0),
            q: Matrix2::new(
                a2 * dt3 * dt / 3.0,
                a2 * dt3 / 2.0,
                a2 * dt3 / 2.0,
                a2 * dt2,
            ),
            r: (meas_std * meas_std).max(MIN_MEAS_VAR),
            limit,
            initial_rate_var: initial_rate_std * initial_rate_std,
        })
    }

    /// Observation entries (the length of `obs` in [`step`](Self::step)).
    pub fn obs_len(&self) -> usize {
        self.len
    }

    /// Readings per tick: the measured channels, in observation order.
    pub fn readings_len(&self) -> usize {
        self.measured
    }

    /// The channels.
    pub fn channels(&self) -> &[Channel] {
        &self.channels[..self.len]
    }

    /// Forgets every estimate (a new episode).
    pub fn reset(&mut self) {
        self.tracks = [IDLE; N];
    }

    /// Whether a reading may reach the estimate.
    fn valid(&self, y: f32) -> bool {
        y.abs() < self.limit
    }

    /// One control tick: `readings` holds the measured channels in observation order
    /// ([`readings_len`](Self::readings_len) values); writes the estimated observation into
    /// `obs` ([`obs_len`](Self::obs_len) values). Invalid readings are rejected and counted
    /// in the report; `obs` is written only when every channel has an estimate.
    pub fn step(&mut self, readings: &[f32], obs: &mut [f32]) -> Result<StepReport> {
        if readings.len() != self.measured {
            return Err(Error::WrongLength {
                input: "readings",
                expected: self.measured,
                found: readings.len(),
            });
        }
        if obs.len() != self.len {
            return Err(Error::WrongLength {
                input: "obs",
                expected: self.len,
                found: obs.len(),
            });
        }
        let mut report = StepReport::default();
        let measured = self.channels[..self.len]
            .iter()
            .enumerate()
            .filter(|(_, c)| c.is_measured());
        for ((index, &channel), &y) in measured.zip(readings) {
            let valid = self.valid(y);
            if !valid {
                report.rejected += 1;
                report.first_rejected.get_or_insert(index);
            }
            let track = &mut self.tracks[index];
            match (channel, track.ready, valid) {
                (Channel::Direct, _, true) => {
                    track.x = Vector2::new(y, 0.0);
                    track.ready = true;
                }
                (Channel::Direct, _, false) | (_, false, false) => {}
                (_, false, true) => {
                    track.x = Vector2::new(y, 0.0);
                    track.p = Matrix2::new(self.r, 0.0, 0.0, self.initial_rate_var);
                    track.ready = true;
                }
                (_, true, valid) => {
                    let angle = channel == Channel::Angle;
                    predict(track, &self.f, &self.q, angle);
                    if valid {
                        update(track, y, self.r, angle);
                    }
                }
            }
        }
        if let Some(index) = (0..self.len).find(|&i| {
            let source = match self.channels[i] {
                Channel::Rate { of, .. } => of,
                _ => i,
            };
            !self.tracks[source].ready
        }) {
            return Err(Error::NotReady { index });
        }
        for (i, out) in obs.iter_mut().enumerate().take(self.len) {
            *out = match self.channels[i] {
                Channel::Rate { of, scale } => scale * self.tracks[of].x[1],
                _ => self.tracks[i].x[0],
            };
        }
        Ok(report)
    }
}

fn predict(track: &mut Track, f: &Matrix2<f32>, q: &Matrix2<f32>, angle: bool) {
    track.x = f * track.x;
    if angle {
        track.x[0] = wrap(track.x[0]);
    }
    track.p = f * track.p * f.transpose() + q;
}

fn update(track: &mut Track, y: f32, r: f32, angle: bool) {
    let h = RowVector2::new(1.0f32, 0.0);
    let mut innovation = y - track.x[0];
    if angle {
        innovation = wrap(innovation);
    }
    let s = track.p[(0, 0)] + r;
    let k: Vector2<f32> = track.p.column(0) / s;
    track.x += k * innovation;
    if angle {
        track.x[0] = wrap(track.x[0]);
    }
    let a = Matrix2::identity() - k * h;
    track.p = a * track.p * a.transpose() + k * k.transpose() * r;
}
