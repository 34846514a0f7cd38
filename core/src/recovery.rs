//! Recovery from motion the prediction got wrong (docs/design.md §1.11): the rule that tells a
//! registration that did not converge, the score that ranks attempts, and the initial guesses
//! tried when the constant-velocity one failed.
//!
//! The rule and its thresholds come from the hard-motion signal study (docs/journal.md,
//! "Which signal tells a lost step"): every lost step ran its last round to LM's iteration
//! limit and no tracked step did; the share of the scan's layers that found a match in the map
//! confirms it (tracked steps 0.73 to 1.0, lost ones 0.04 to 0.82). Both are counts the
//! registration has anyway, so a frame that converges pays nothing.
//!
//! The guesses keep the last pose's position and turn it about the world's vertical: a
//! hand-held rig or a drone turns fastest in yaw, and position and tilt errors of the size
//! they make between scans are within the coarse rounds' reach (two cells). The turn the
//! scans' azimuth profiles find ([`crate::azimuth`]) gives the first guess where it and the
//! prediction disagree ([`profile_guess`], [`profile_disagrees`]), orders the others, and
//! confirms a plausible attempt ([`agrees_with_profile`]).

use crate::config::RecoveryConfig;
use crate::math::{rotation_angle, turned_in_yaw, wrapped_angle, Pose, Vec3};
use nalgebra::{UnitQuaternion, Vector3};

/// What one registration attempt ended with, enough to judge it and compare it with others.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Verdict {
    /// The last round's LM ran to its iteration limit.
    pub hit_limit: bool,
    /// Share of the scan's layers that found a match in the map in the last round.
    pub matched_share: f64,
    /// The last round moved the sensor by at most `settle_m` and turned it by at most
    /// `settle_deg`: the rounds agree.
    pub settled: bool,
}

impl Verdict {
    /// The verdict of a last round that paired `residuals` of `layers` scan layers, ran LM
    /// for `iterations` of at most `max_iterations`, and took the sensor from pose `before` to
    /// `after`. Settling is judged on how far the sensor moved and turned, wherever the
    /// world's origin lies (a correction's own translation, about the world's origin, grows
    /// with the distance from it).
    #[allow(clippy::too_many_arguments)]
    pub fn of(
        residuals: usize,
        layers: usize,
        iterations: usize,
        max_iterations: usize,
        before: &Pose,
        after: &Pose,
        cfg: &RecoveryConfig,
    ) -> Self {
        let motion = before.inverse() * after;
        Self {
            hit_limit: iterations >= max_iterations,
            matched_share: if layers == 0 {
                0.0
            } else {
                residuals as f64 / layers as f64
            },
            settled: motion.translation.vector.norm() <= cfg.settle_m
                && rotation_angle(&motion) <= cfg.settle_deg.to_radians(),
        }
    }

    /// True when the attempt did not converge: it is [stuck](Self::is_stuck), or it still
    /// moved the sensor by more than the settling limits. This is what sends a frame to
    /// recovery.
    pub fn is_lost(&self, cfg: &RecoveryConfig) -> bool {
        self.is_stuck(cfg) || !self.settled
    }

    /// True when the last round ran to the iteration limit with less than
    /// `cfg.confirm_share` of the scan's layers matched.
    pub fn is_stuck(&self, cfg: &RecoveryConfig) -> bool {
        self.hit_limit && self.matched_share < cfg.confirm_share
    }

    /// True when the attempt surely converged: its last round stopped before the limit, with
    /// at least `cfg.confirm_share` of its layers matched, and settled. A guess that does this
    /// ends recovery.
    pub fn is_sure(&self, cfg: &RecoveryConfig) -> bool {
        !self.hit_limit && self.settled && self.matched_share >= cfg.confirm_share
    }

    /// True when the attempt converged and settled with at least `cfg.accept_share` of its
    /// layers matched: when no guess was sure, such a one is kept as recovered (a turn into
    /// unseen space leaves fewer layers with a match).
    pub fn is_plausible(&self, cfg: &RecoveryConfig) -> bool {
        !self.hit_limit && self.settled && self.matched_share >= cfg.accept_share
    }

    /// The score that ranks attempts: the matched share, a sure attempt above every other and
    /// a plausible one above the rest.
    pub fn score(&self, cfg: &RecoveryConfig) -> f64 {
        self.matched_share
            + if self.is_sure(cfg) {
                2.0
            } else if self.is_plausible(cfg) {
                1.0
            } else {
                0.0
            }
    }
}

/// The initial guesses to try after the prediction failed: the last pose itself (no motion),
/// then turned about the world's vertical by `±step`, `±2·step`, ... up to `yaw_max_deg`;
/// nearest first, or, given the heading change the scans' azimuth profiles found
/// (`towards`, radians), nearest that first. At most [`MAX_GUESSES`].
pub fn guesses(
    last: &Pose,
    cfg: &RecoveryConfig,
    towards: Option<f64>,
) -> impl Iterator<Item = Pose> {
    let step = cfg.yaw_step_deg.to_radians();
    let turns = if step > 0.0 {
        libm::floor(cfg.yaw_max_deg / cfg.yaw_step_deg + 1e-9) as usize
    } else {
        0
    };
    let turns = turns.min((MAX_GUESSES - 1) / 2);
    // 0, +1, -1, +2, -2, ... steps.
    let mut ks = [0.0f64; MAX_GUESSES];
    for (i, k) in ks.iter_mut().enumerate().take(2 * turns + 1) {
        *k = i.div_ceil(2) as f64 * if i % 2 == 1 { 1.0 } else { -1.0 };
    }
    let n = 2 * turns + 1;
    if let Some(towards) = towards {
        // Among equals, the smaller turn first, and the positive before the negative.
        let off = |k: f64| wrapped_angle(k * step - towards).abs();
        ks[..n].sort_unstable_by(|&a, &b| {
            off(a)
                .total_cmp(&off(b))
                .then(a.abs().total_cmp(&b.abs()))
                .then(b.total_cmp(&a))
        });
    }
    let last = *last;
    (0..n).map(move |i| turned_in_yaw(&last, ks[i] * step))
}

/// The heading change about the world's vertical from `last` to `to` (radians): where the
/// sensor's `x` axis points, seen from above.
pub fn heading_change(last: &Pose, to: &Pose) -> f64 {
    wrapped_angle(
        yaw_about_sensor_vertical(&to.rotation) - yaw_about_sensor_vertical(&last.rotation),
    )
}

/// The guess from the scans' azimuth profiles ([`crate::azimuth`]): the `last` pose turned by
/// `profile_yaw` (the turn about the sensor's vertical that the profiles found) and moved by
/// `world_step` (the last step as the world saw it: the prediction's own step turns with the
/// heading it got wrong).
pub fn profile_guess(last: &Pose, world_step: &Vec3, profile_yaw: f64) -> Pose {
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), profile_yaw);
    Pose::from_parts(
        (last.translation.vector + world_step).into(),
        last.rotation * turn,
    )
}

/// True when the profiles' guess turns from the `last` pose by more than
/// `cfg.profile_disagree_deg` about the sensor's vertical away from the `predicted` pose:
/// registration then starts from the profiles' guess.
pub fn profile_disagrees(
    last: &Pose,
    predicted: &Pose,
    profile: &Pose,
    cfg: &RecoveryConfig,
) -> bool {
    let yaw = |p: &Pose| yaw_about_sensor_vertical(&(last.rotation.inverse() * p.rotation));
    wrapped_angle(yaw(profile) - yaw(predicted)).abs() > cfg.profile_disagree_deg.to_radians()
}

/// True when an attempt ended within half a yaw step of the profiles' guess in heading (its
/// tilt may differ: the profiles do not see tilt): two cues agree, and a plausible attempt
/// there ends recovery.
pub fn agrees_with_profile(pose: &Pose, profile: &Pose, cfg: &RecoveryConfig) -> bool {
    let yaw = yaw_about_sensor_vertical(&(profile.rotation.inverse() * pose.rotation));
    yaw.abs() <= 0.5 * cfg.yaw_step_deg.to_radians()
}

/// The heading of a rotation: where it takes the `x` axis, seen from above its frame's
/// vertical (a sensor's heading in the world for a pose's rotation, the turn about the
/// sensor's vertical for a relative one).
fn yaw_about_sensor_vertical(r: &UnitQuaternion<f64>) -> f64 {
    let x = r * Vector3::x();
    libm::atan2(x.y, x.x)
}

/// Most guesses [`guesses`] gives (the last pose and 24 turns each way: 7.5° steps all round).
pub const MAX_GUESSES: usize = 49;

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec::Vec;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// The defaults, with settling limits of 5 cm and 0.5° (round numbers for the cases).
    fn cfg() -> RecoveryConfig {
        RecoveryConfig {
            settle_m: 0.05,
            settle_deg: 0.5,
            ..crate::config::Config::default().register.recovery
        }
    }

    #[test]
    fn guesses_turn_the_last_pose_about_the_vertical_nearest_first() {
        let last = Pose::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        );
        let g: Vec<Pose> = guesses(&last, &cfg(), None).collect();
        assert_eq!(g.len(), 25);
        assert_eq!(g[0], last);
        let turns: Vec<f64> = g
            .iter()
            .map(|p| {
                let d = p.rotation * last.rotation.inverse();
                let axis = d.axis().map_or(1.0, |a| a.z.signum());
                (axis * d.angle()).to_degrees()
            })
            .collect();
        for (i, t) in turns.iter().enumerate().skip(1) {
            let k = i.div_ceil(2) as f64 * if i % 2 == 1 { 1.0 } else { -1.0 };
            assert!(
                (t - 15.0 * k).abs() < 1e-6 || (t.abs() - 180.0).abs() < 1e-6,
                "{i}: {t}"
            );
            assert_eq!(g[i].translation, last.translation);
            // A turn about the vertical keeps the tilt: the sensor's z axis keeps its height.
            let up = |p: &Pose| (p.rotation * Vector3::z()).z;
            assert!((up(&g[i]) - up(&last)).abs() < 1e-12);
        }
        assert!(rotation_angle(&(g[1].inverse() * g[2])) > 0.5);
    }

    #[test]
    fn guesses_towards_the_profiles_turn_come_nearest_it_first_and_are_the_same_set() {
        let last = Pose::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        );
        let plain: Vec<Pose> = guesses(&last, &cfg(), None).collect();
        let towards: Vec<Pose> = guesses(&last, &cfg(), Some(f64::to_radians(-50.0))).collect();
        assert_eq!(towards.len(), plain.len());
        for g in &plain {
            assert!(towards.contains(g));
        }
        let turn = |p: &Pose| heading_change(&last, p).to_degrees();
        // -45 and -60 are nearest -50, then -30, -75, ...
        let first: Vec<f64> = towards[..4].iter().map(|p| libm::round(turn(p))).collect();
        assert_eq!(first, [-45.0, -60.0, -30.0, -75.0]);
        // Far from the profiles' turn: half round, last.
        assert!((turn(towards.last().unwrap()) - 130.0).abs() < 10.0);
    }

    #[test]
    fn the_profiles_guess_turns_the_last_pose_about_its_vertical_and_steps_as_the_world_did() {
        let last = Pose::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.1, -0.05, 0.3),
        );
        let step = Vec3::new(0.5, -0.2, 0.0);
        let yaw = f64::to_radians(30.0);
        let g = profile_guess(&last, &step, yaw);
        assert!((g.translation.vector - last.translation.vector - step).norm() < 1e-12);
        // Turned about the sensor's own vertical: the sensor's z axis stays where it was.
        let up = |p: &Pose| p.rotation * Vector3::z();
        assert!((up(&g) - up(&last)).norm() < 1e-12);
        assert!((rotation_angle(&(last.inverse() * g)) - yaw).abs() < 1e-12);
        // The prediction that turned 28 degrees agrees with it, one that turned 10 does not.
        let c = cfg();
        let predicted = |deg: f64| profile_guess(&last, &Vec3::zeros(), deg.to_radians());
        assert!(!profile_disagrees(&last, &predicted(28.0), &g, &c));
        assert!(profile_disagrees(&last, &predicted(10.0), &g, &c));
        assert!(profile_disagrees(&last, &predicted(-150.0), &g, &c));
        // An attempt within half a yaw step (7.5 degrees) of it in heading agrees, whatever
        // its tilt; one 10 degrees off does not.
        let tilted = Pose::from_parts(
            g.translation,
            g.rotation * UnitQuaternion::from_euler_angles(0.15, 0.0, f64::to_radians(5.0)),
        );
        assert!(agrees_with_profile(&tilted, &g, &c));
        assert!(!agrees_with_profile(&predicted(40.0), &g, &c));
    }

    #[test]
    fn no_step_gives_the_last_pose_only_and_the_count_is_bounded() {
        let mut c = cfg();
        c.yaw_step_deg = 0.0;
        assert_eq!(guesses(&Pose::identity(), &c, None).count(), 1);
        c.yaw_step_deg = 0.001;
        assert_eq!(guesses(&Pose::identity(), &c, None).count(), MAX_GUESSES);
    }

    #[test]
    fn a_small_turn_settles_as_well_far_from_the_world_origin_as_near_it() {
        let c = cfg();
        // The same step, a tenth of a degree in yaw, at the origin and 3 km from it.
        let turn = Pose::rotation(Vector3::z() * 0.1f64.to_radians());
        let far = Pose::translation(3000.0, 0.0, 0.0);
        // As a correction about the world's origin, the far one translates by over 5 m.
        assert!((far * turn * far.inverse()).translation.vector.norm() > 5.0);
        for at in [Pose::identity(), far] {
            assert!(Verdict::of(95, 100, 3, 10, &at, &(at * turn), &c).settled);
        }
    }

    #[test]
    fn a_lost_attempt_ran_to_the_limit_and_matched_little_or_did_not_settle() {
        let c = cfg();
        let still = Pose::identity();
        let v = |res, layers, it, corr: &Pose| Verdict::of(res, layers, it, 10, &still, corr, &c);
        assert!(v(40, 100, 10, &still).is_lost(&c));
        assert!(!v(90, 100, 10, &still).is_lost(&c));
        assert!(!v(40, 100, 9, &still).is_lost(&c));
        assert!(v(0, 0, 10, &still).is_lost(&c));
        // A last round that still moved the sensor by 10 cm, or by a degree, did not settle.
        let moved = Pose::translation(0.1, 0.0, 0.0);
        let turned = Pose::rotation(Vector3::z() * 1f64.to_radians());
        assert!(v(95, 100, 3, &moved).is_lost(&c));
        assert!(v(95, 100, 3, &turned).is_lost(&c));
        assert!(!v(95, 100, 3, &Pose::translation(0.04, 0.0, 0.0)).is_lost(&c));
        // Sure: stopped before the limit, settled, with most layers matched; it ranks above
        // the rest.
        assert!(v(90, 100, 3, &still).is_sure(&c));
        assert!(!v(40, 100, 3, &still).is_sure(&c));
        assert!(!v(90, 100, 10, &still).is_sure(&c));
        assert!(!v(90, 100, 3, &moved).is_sure(&c));
        assert!(v(86, 100, 3, &still).score(&c) > v(99, 100, 10, &still).score(&c));
        assert!(v(60, 100, 10, &still).score(&c) > v(40, 100, 3, &still).score(&c));
        // Plausible: converged and settled with a share between the two thresholds; it ranks
        // between the sure ones and the rest.
        assert!(v(70, 100, 3, &still).is_plausible(&c) && !v(70, 100, 3, &still).is_sure(&c));
        assert!(!v(50, 100, 3, &still).is_plausible(&c));
        assert!(!v(70, 100, 3, &moved).is_plausible(&c));
        assert!(v(86, 100, 3, &still).score(&c) > v(70, 100, 3, &still).score(&c));
        assert!(v(70, 100, 3, &still).score(&c) > v(84, 100, 10, &still).score(&c));
    }
}
