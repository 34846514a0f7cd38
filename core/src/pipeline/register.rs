//! Registration of one scan (docs/design.md §1.4): rounds from one initial guess (the
//! prediction, or the turn the scans' azimuth profiles found where the two disagree), and the
//! recovery that tries other guesses when that did not converge (§1.11). Leaves the map alone;
//! the pipeline fuses the attempt it returns.

use super::{Pipeline, RegistrationStatus, ScanStats};
use crate::associate::{associate, AssociateStats};
use crate::bucket::BucketStats;
use crate::capacity::Capacity;
use crate::config::LmConfig;
use crate::executor::Executor;
use crate::lm::{self, LmError};
use crate::math::{renormalized, rotation_angle, Pose};
use crate::real::Real;
use crate::reconstruct::Purpose;
use crate::recovery::{self, Verdict};
use crate::stage::{Probe, Stage};

/// One registration from one initial guess.
#[derive(Debug, Clone, Copy)]
pub(super) struct Attempt {
    pub(super) pose: Pose,
    pub(super) status: RegistrationStatus,
    pub(super) verdict: Verdict,
    /// Association of the last round.
    pub(super) associate: AssociateStats,
    pub(super) conditioning: f64,
    pub(super) degenerate_directions: usize,
    /// The last solve's information ([`lm::PoseInformation`]).
    pub(super) information: lm::PoseInformation,
    /// The last solve's residuals' root mean square ([`ScanStats::residual_rms_m`]).
    pub(super) residual_rms_m: f64,
    /// Without `MapConfig::reconstruct_at_final_pose`: the last round's bucketing and the pose
    /// its reconstruction (left in the scan's buffer) was made at.
    pub(super) for_update: Option<(BucketStats, Pose)>,
}

impl Attempt {
    /// No registration: the pose as given, judged lost.
    pub(super) fn unregistered(pose: Pose) -> Self {
        Attempt {
            pose,
            status: RegistrationStatus::NotConverged,
            verdict: Verdict::default(),
            associate: AssociateStats::default(),
            conditioning: 0.0,
            degenerate_directions: 0,
            information: lm::PoseInformation::default(),
            residual_rms_m: 0.0,
            for_update: None,
        }
    }
}

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// Registers the filtered scan from the prediction `predicted`, or from the turn the scans'
    /// azimuth profiles found (`profile_yaw`) where the two disagree
    /// ([`recovery::profile_disagrees`]; back to the prediction when the scan cannot check
    /// that turn): the rounds of docs/design.md §1.4, then, when they did not converge,
    /// recovery (§1.11). A frame that converged from the profiles' start, or from a prediction
    /// turning more than `polish_turn_deg`, is polished, as a recovered one is.
    pub(super) fn register_scan(
        &mut self,
        predicted: Pose,
        profile_yaw: Option<f64>,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) -> Attempt {
        let r = self.config.register;
        let (rounds, reach) = if self.motion.velocity_known() {
            (r.iterations, r.cross_cell_overlap)
        } else {
            (r.initial_iterations, r.initial_cross_cell_overlap)
        };
        let profile = match (self.motion.last(), profile_yaw) {
            (Some(last), Some(yaw)) => Some(recovery::profile_guess(
                &last,
                &self.motion.world_step(),
                yaw,
            )),
            _ => None,
        };
        let mut by_profile = profile.filter(|g| {
            self.motion
                .last()
                .is_some_and(|last| recovery::profile_disagrees(&last, &predicted, g, &r.recovery))
        });
        let mut best = match by_profile {
            Some(guess) => self.register(
                guess,
                r.recovery.profile_rounds,
                r.initial_cross_cell_overlap,
                &r.lm,
                exec,
                probe,
                stats,
            ),
            None => self.register(predicted, rounds, reach, &r.lm, exec, probe, stats),
        };
        if by_profile.is_some() && best.status != RegistrationStatus::Converged {
            // The scan could not check the profiles' turn (too few matches, a degenerate
            // scene, a failed solve): what the motion model says stands, as without them.
            by_profile = None;
            best = self.register(predicted, rounds, reach, &r.lm, exec, probe, stats);
        }
        let start = by_profile.unwrap_or(predicted);
        let turn = self
            .motion
            .last()
            .map_or(0.0, |last| rotation_angle(&(last.inverse() * start)));
        // From the profiles' start the polish also settles what the rounds left moving.
        let polishable = if by_profile.is_some() {
            !best.verdict.is_stuck(&r.recovery)
        } else {
            turn > r.recovery.polish_turn_deg.to_radians() && !best.verdict.is_lost(&r.recovery)
        };
        if polishable && best.status == RegistrationStatus::Converged {
            // Polished first: a polish that ends lost sends the frame to recovery.
            best = self.polish(best, exec, probe, stats);
        }
        if best.verdict.is_lost(&r.recovery) {
            if r.recovery.enabled {
                best = self.recover(best, (start, predicted), profile, exec, probe, stats);
            } else if best.status == RegistrationStatus::Converged {
                best.status = RegistrationStatus::NotConverged;
            }
        }
        best
    }

    /// Registers the filtered scan from `start` in `rounds` rounds, all but the last with
    /// cross-cell `reach` (docs/design.md §1.4), LM with `lm_config`. Counts rounds,
    /// iterations and dropped layers into `stats`; leaves the map alone.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn register(
        &mut self,
        start: Pose,
        rounds: usize,
        reach: u32,
        lm_config: &LmConfig,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) -> Attempt {
        let r = self.config.register;
        let mut a = Attempt {
            pose: start,
            status: RegistrationStatus::Converged,
            verdict: Verdict::default(),
            associate: AssociateStats::default(),
            conditioning: 0.0,
            degenerate_directions: 0,
            information: lm::PoseInformation::default(),
            residual_rms_m: 0.0,
            for_update: None,
        };
        for round in 0..rounds {
            let last = round + 1 == rounds;
            let reach = if last { 0 } else { reach };
            let purpose = self.round_purpose(last, reach);
            let (b, made) = self.reconstruct(&a.pose, exec, purpose, probe);
            stats.dropped_layers += made.dropped;
            if purpose == Purpose::Update {
                a.for_update = Some((b, a.pose));
            }
            probe.enter(Stage::Associate);
            a.associate = associate::<R>(
                &self.scan,
                &self.map,
                reach,
                self.stale_before(),
                r.variance_register,
                &mut self.residuals,
                exec,
            );
            stats.rounds += 1;
            probe.enter(Stage::Solve);
            if !self.solve_round(&mut a, made.unpaired, lm_config, stats) {
                break;
            }
        }
        a
    }

    /// What a round with cross-cell `reach` reconstructs for: the map update's own layers in
    /// the `last` round when they are reused for it, registration's otherwise. Every layer has
    /// exact variances either way: registration pairs the same vertices as with `Register` (it
    /// only compares variances with its threshold).
    fn round_purpose(&self, last: bool, reach: u32) -> Purpose {
        if last && !self.config.map.reconstruct_at_final_pose {
            Purpose::Update
        } else {
            Purpose::Register {
                reach,
                half_cells: reach > 0 && self.config.register.coarse_half_cells,
                since: self.stale_before(),
            }
        }
    }

    /// Solves the round's pairs (`unpaired` layers found none) from `a.pose` and takes the
    /// outcome into `a`, the iterations into `stats`; false when the solve failed, which ends
    /// the attempt.
    fn solve_round(
        &self,
        a: &mut Attempt,
        unpaired: usize,
        lm_config: &LmConfig,
        stats: &mut ScanStats,
    ) -> bool {
        let verdict = |residuals, iterations, before: &Pose, after: &Pose| {
            Verdict::of(
                residuals,
                self.scan.len() + unpaired,
                iterations,
                lm_config.max_iterations,
                before,
                after,
                &self.config.register.recovery,
            )
        };
        match lm::solve(&self.residuals, lm_config) {
            Ok(sol) => {
                let pose = renormalized(sol.correction * a.pose);
                a.verdict = verdict(a.associate.residuals, sol.iterations, &a.pose, &pose);
                a.pose = pose;
                stats.lm_iterations += sol.iterations;
                a.conditioning = sol.conditioning;
                a.degenerate_directions = sol.degenerate_directions;
                a.information = sol.information;
                a.residual_rms_m = sol.residual_rms();
                if sol.degenerate_directions > 0 {
                    a.status = RegistrationStatus::Degenerate;
                }
                true
            }
            Err(e) => {
                // A scan too degenerate to solve is not lost, nor one with too few layers
                // to pair from any guess; one that found too little to pair, or numbers
                // that blew up, may be.
                let n = a.associate.residuals;
                a.verdict = verdict(n, lm_config.max_iterations, &a.pose, &a.pose);
                a.status = match e {
                    LmError::TooFewResiduals { .. } => {
                        a.verdict.hit_limit = self.scan.len() + unpaired >= lm_config.min_residuals;
                        RegistrationStatus::TooFewResiduals
                    }
                    LmError::Degenerate { conditioning } => {
                        a.verdict.hit_limit = false;
                        a.conditioning = conditioning;
                        a.degenerate_directions = 6;
                        RegistrationStatus::Degenerate
                    }
                    LmError::NotFinite => RegistrationStatus::SolverFailed,
                };
                false
            }
        }
    }

    /// Registers the scan again from the guesses of [`recovery::guesses`] around the last
    /// pose (nearest the scans' azimuth profiles' turn first, when they found one: `profile`),
    /// after `first` (from `start`: `predicted`, the motion model's or a prior, or the
    /// profiles' guess) did not converge;
    /// stops at the first sure attempt, or a plausible one that agrees with the profiles, and
    /// returns the best by [`Verdict::score`] (docs/design.md §1.11).
    pub(super) fn recover(
        &mut self,
        first: Attempt,
        (start, predicted): (Pose, Pose),
        profile: Option<Pose>,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) -> Attempt {
        let r = self.config.register;
        let rc = r.recovery;
        let last = self.motion.last().unwrap_or(first.pose);
        // First from where the first attempt ended (more rounds, wider reach), then from the
        // prediction if the first attempt started from the profiles' guess, then from the last
        // pose turned (about the profiles' turn).
        let towards = profile.map(|p| recovery::heading_change(&last, &p));
        let guesses = core::iter::once(first.pose)
            .chain((start != predicted).then_some(predicted))
            .chain(recovery::guesses(&last, &rc, towards));
        let mut best = first;
        // The scan's buffers hold the attempt run last: the best's reconstruction is reusable
        // for the map update only while it is that one.
        let mut best_ran_last = true;
        for guess in guesses {
            if guess == start && start == predicted {
                continue;
            }
            stats.recovery_attempts += 1;
            let a = self.register(
                guess,
                rc.rounds,
                r.initial_cross_cell_overlap,
                &r.lm,
                exec,
                probe,
                stats,
            );
            let done = a.verdict.is_sure(&rc)
                || (a.verdict.is_plausible(&rc)
                    && profile.is_some_and(|p| recovery::agrees_with_profile(&a.pose, &p, &rc)));
            best_ran_last = a.verdict.score(&rc) > best.verdict.score(&rc);
            if best_ran_last {
                best = a;
            }
            if done {
                break;
            }
        }
        if !best_ran_last {
            best.for_update = None;
        }
        if matches!(
            best.status,
            RegistrationStatus::Converged | RegistrationStatus::Degenerate
        ) {
            best.status = if best.verdict.is_plausible(&rc) {
                RegistrationStatus::Recovered
            } else {
                RegistrationStatus::NotConverged
            };
        }
        if best.status == RegistrationStatus::Recovered {
            best = self.polish(best, exec, probe, stats);
        }
        best
    }

    /// Refines an attempt after a fast turn (recovered, or converged from a prediction that
    /// turned far): `polish_rounds` rounds from its pose with no cross-cell reach and LM's
    /// Huber threshold at `polish_huber_delta_m`, kept (with the attempt's status) when they
    /// converge and settle (docs/design.md §1.11). The search's wide threshold lets it reach a
    /// pose far from the guess; near it, the tight one gives wrong pairs less pull.
    pub(super) fn polish(
        &mut self,
        attempt: Attempt,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) -> Attempt {
        let rc = self.config.register.recovery;
        if rc.polish_rounds == 0 {
            return attempt;
        }
        let lm_config = LmConfig {
            huber_delta_m: rc.polish_huber_delta_m,
            ..self.config.register.lm
        };
        let mut polished = self.register(
            attempt.pose,
            rc.polish_rounds,
            0,
            &lm_config,
            exec,
            probe,
            stats,
        );
        if polished.status == RegistrationStatus::Converged && polished.verdict.settled {
            polished.status = attempt.status;
            polished
        } else {
            // The scan's buffers hold the polishing rounds now, not the recovered attempt's.
            Attempt {
                for_update: None,
                ..attempt
            }
        }
    }
}
