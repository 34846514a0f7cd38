//! Localizing a scan in a known map with no pose to start from (docs/design.md §1.13): the
//! coarse hypotheses of [`crate::relocalize`], the best registered in full as recovery
//! registers its guesses (§1.11), and the judgement. Fuses the scan only when the map takes
//! updates and the pose was found.

use super::register::Attempt;
use super::{Pipeline, RegistrationStatus, ScanOutcome, ScanStats};
use crate::capacity::Capacity;
use crate::executor::Executor;
use crate::math::{turned_in_yaw, Pose};
use crate::motion::ConstantVelocity;
use crate::real::Real;
use crate::relocalize::{
    same_place, surface_hits, Hits, Paging, Search, Shortlist, CHUNK, MAX_KEEP, MAX_YAW_STEPS,
};
use crate::stage::{Probe, Stage};

/// What a search for the pose found ([`Known::Somewhere`](super::Known::Somewhere)).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Relocalized {
    /// The scan's outcome: status [`RegistrationStatus::Relocalized`] with the pose found, or
    /// [`RegistrationStatus::NotLocalized`] with the best attempt's pose (not to be trusted).
    pub outcome: ScanOutcome,
    /// Hypotheses scored coarsely (candidates × headings).
    pub hypotheses: usize,
    /// Hypotheses registered in full.
    pub registered: usize,
    /// Share of the scan's points on the map's surface at the best pose.
    pub hit_share: f64,
    /// Share of the scan's points on the map's walls (x and y layers) at the best pose.
    pub wall_share: f64,
    /// Whether the best pose's registration converged and settled (a pose that did not is
    /// never accepted).
    pub settled: bool,
    /// The same at the best pose elsewhere (0 when every attempt ended at the best's place).
    pub runner_up_share: f64,
}

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// The search for a filtered scan's pose ([`Known::Somewhere`](super::Known::Somewhere)):
    /// each of `candidates` turned to `search.yaw_steps` headings is scored coarsely, the
    /// `search.keep` best distinct ones are registered in full, and the best registered pose
    /// is accepted when its registration settled, enough of the scan lies on the map there
    /// (`search.min_hit_share`, `search.min_wall_share`) and no pose elsewhere explains
    /// `search.ambiguity_ratio` as much.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn relocalize(
        &mut self,
        mut stats: ScanStats,
        candidates: &[Pose],
        search: &Search,
        exec: &impl Executor,
        probe: &mut impl Probe,
        paging: &mut (dyn Paging + Send),
    ) -> Relocalized {
        let (shortlist, hypotheses) =
            self.coarse_shortlist(candidates, search, exec, probe, paging);
        let tried = self.register_shortlist(&shortlist, search, exec, probe, paging, &mut stats);
        let registered = shortlist.items().len();
        // The best: settled first, then by share; the runner-up: the best settled one elsewhere.
        let rank = |t: &(bool, Hits, Attempt)| (t.0, t.1.share());
        let best = tried.iter().max_by(|x, y| {
            rank(x)
                .partial_cmp(&rank(y))
                .unwrap_or(core::cmp::Ordering::Equal)
        });
        let (settled, hits, attempt) = match best {
            Some(b) => *b,
            None => (
                false,
                Hits::default(),
                Attempt::unregistered(Pose::identity()),
            ),
        };
        let (hit_share, wall_share) = (hits.share(), hits.wall_share());
        let runner_up = tried
            .iter()
            .filter(|(s, _, a)| *s && !same_place(&a.pose, &attempt.pose, search))
            .map(|(_, h, _)| h.share())
            .fold(0.0f64, f64::max);
        stats.associate = attempt.associate;
        stats.conditioning = attempt.conditioning;
        stats.degenerate_directions = attempt.degenerate_directions;
        stats.information = attempt.information;
        stats.residual_rms_m = attempt.residual_rms_m;
        let found = settled
            && hit_share >= search.min_hit_share
            && wall_share >= search.min_wall_share
            && runner_up < search.ambiguity_ratio * hit_share;
        let pose = attempt.pose;
        paging.around(&mut self.map, &pose);
        let status = if found {
            self.motion = ConstantVelocity::new();
            if self.map_updates {
                self.finish(pose, exec, probe, &mut stats);
            } else {
                self.motion.push(pose);
            }
            RegistrationStatus::Relocalized
        } else {
            RegistrationStatus::NotLocalized
        };
        Relocalized {
            outcome: self.outcome(pose, status, stats),
            hypotheses,
            registered,
            hit_share,
            wall_share,
            settled,
            runner_up_share: runner_up,
        }
    }

    /// Every candidate turned to `search.yaw_steps` headings, scored coarsely against the map
    /// (a subsample of the scan within `search.coarse_tol_m` of its surfaces), candidates spread
    /// over the executor's workers and offered to the shortlist in candidate order, so the
    /// result does not depend on the executor. Returns the shortlist and the hypotheses scored.
    fn coarse_shortlist(
        &mut self,
        candidates: &[Pose],
        search: &Search,
        exec: &impl Executor,
        probe: &mut impl Probe,
        paging: &mut (dyn Paging + Send),
    ) -> (Shortlist, usize) {
        let lattice = self.config.lattice().table();
        let max_var = self.config.register.variance_register as f32;
        // The coarse score's subsample: every k-th filtered point.
        let stride = (self.points.len() / search.coarse_points.max(1)).max(1);
        let mut shortlist = Shortlist::new(search.keep);
        let steps = search.yaw_steps.clamp(1, MAX_YAW_STEPS);
        let yaw = |k: usize| core::f64::consts::TAU * k as f64 / steps as f64;
        let mut hypotheses = 0;
        probe.enter(Stage::Associate);
        for chunk in candidates.chunks(CHUNK) {
            if let Some(middle) = chunk.get(chunk.len() / 2) {
                paging.around(&mut self.map, middle);
            }
            let (map, points) = (&self.map, &self.points);
            exec.map_in_order(
                chunk,
                || (),
                |_, c| {
                    let mut hits = [0usize; MAX_YAW_STEPS];
                    for (k, h) in hits.iter_mut().enumerate().take(steps) {
                        let sample = points.iter().step_by(stride);
                        let pose = turned_in_yaw(c, yaw(k));
                        *h = surface_hits(
                            map,
                            &lattice,
                            sample,
                            &pose,
                            search.coarse_tol_m,
                            max_var,
                        )
                        .any;
                    }
                    hits
                },
                |hits| {
                    let c = candidates
                        .get(hypotheses / steps)
                        .copied()
                        .unwrap_or_else(Pose::identity);
                    for (k, h) in hits.iter().enumerate().take(steps) {
                        shortlist.offer(*h, turned_in_yaw(&c, yaw(k)), search);
                        hypotheses += 1;
                    }
                },
            );
        }
        probe.enter(Stage::Done);
        (shortlist, hypotheses)
    }

    /// Each shortlisted guess registered in full as recovery registers its guesses (polished
    /// when it converged plausibly): whether it converged and settled, its share of the scan on
    /// the map's surfaces (within `search.fine_tol_m`), and the attempt.
    fn register_shortlist(
        &mut self,
        shortlist: &Shortlist,
        search: &Search,
        exec: &impl Executor,
        probe: &mut impl Probe,
        paging: &mut (dyn Paging + Send),
        stats: &mut ScanStats,
    ) -> heapless::Vec<(bool, Hits, Attempt), MAX_KEEP> {
        let lattice = self.config.lattice().table();
        let max_var = self.config.register.variance_register as f32;
        let r = self.config.register;
        let mut tried = heapless::Vec::new();
        for &(_, guess) in shortlist.items() {
            stats.recovery_attempts += 1;
            paging.around(&mut self.map, &guess);
            let mut a = self.register(
                guess,
                r.recovery.rounds,
                r.initial_cross_cell_overlap,
                &r.lm,
                exec,
                probe,
                stats,
            );
            if a.status == RegistrationStatus::Converged && a.verdict.is_plausible(&r.recovery) {
                a = self.polish(a, exec, probe, stats);
            }
            let hits = surface_hits(
                &self.map,
                &lattice,
                self.points.iter(),
                &a.pose,
                search.fine_tol_m,
                max_var,
            );
            let settled = matches!(
                a.status,
                RegistrationStatus::Converged | RegistrationStatus::Degenerate
            ) && a.verdict.is_plausible(&r.recovery);
            let _ = tried.push((settled, hits, a));
        }
        tried
    }
}
