//! Sweeps: a stream of firings (from any spinning sensor's packets) cut into scans, one a
//! turn, at a chosen azimuth.
//!
//! What it guarantees: a sweep holds the firings from one crossing of the cut azimuth to the
//! next, each with its own position and time, as decoded; a packet that never came leaves a
//! gap (counted in the sweep, [`Sweep::gaps`]) and shifts or bends nothing. The firings before
//! the first crossing and after the last one make no sweep (a part turn), and are counted.

use slamesh_core::Point;

/// One turn of the sensor.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Sweep {
    /// Sensor-frame points, in firing order.
    pub points: Vec<Point>,
    /// Each point's firing time (seconds, the sensor's clock).
    pub times: Vec<f64>,
    /// Packets missing inside it (by the time between the packets that came).
    pub gaps: u32,
}

impl Sweep {
    /// The sweep's stamp: the middle of its firings' times. A deskewed sweep's points, and the
    /// pose estimated from them, are the sensor's at that time (`slamesh_core::deskew` moves
    /// points to the middle of their span), so the stamps and the poses agree from the first
    /// deskewed frame on.
    pub fn stamp(&self) -> Option<f64> {
        Some((self.times.first()? + self.times.last()?) / 2.0)
    }

    /// Each point's time relative to the stamp (seconds), as frame sources hand them out.
    pub fn relative_times(&self) -> Vec<f32> {
        let stamp = self.stamp().unwrap_or(0.0);
        self.times.iter().map(|t| (t - stamp) as f32).collect()
    }
}

/// Cuts firings into sweeps.
#[derive(Debug)]
pub struct Sweeps {
    cut: u16,
    /// The last firing's azimuth past the cut (hundredths of a degree, 0 to 35 999).
    last: Option<u32>,
    /// The sweep being filled; `None` before the first crossing.
    current: Option<Sweep>,
    /// The last packet's time and the packets' period, for gaps.
    last_packet: Option<f64>,
    /// Firings before the first crossing or in a sweep cut off at the end: no sweep.
    pub partial_firings: u64,
    /// Packets missing, over all sweeps.
    pub gaps: u64,
    /// Times that went back, or forward by more than [`MAX_GAP_S`]: the sweep being filled is
    /// dropped there (its firings counted as part turns), not stretched over the jump.
    pub time_jumps: u64,
    /// A stream's first firing within this of the cut starts a sweep, and a last one within
    /// this of the next cut ends one (hundredths of a degree; 0: only crossings count).
    whole_within: u32,
}

/// The longest time between two packets that is a gap in one stream; a longer one (or a
/// time going back) is a jump: a restarted sensor or a spliced capture.
pub const MAX_GAP_S: f64 = 1.0;

impl Sweeps {
    /// Sweeps cut at `cut_deg` degrees of azimuth.
    pub fn new(cut_deg: f64) -> Self {
        let cut = (cut_deg.rem_euclid(360.0) * 100.0).round() as u32 % 36_000;
        Self {
            cut: cut as u16,
            last: None,
            current: None,
            last_packet: None,
            partial_firings: 0,
            gaps: 0,
            time_jumps: 0,
            whole_within: 0,
        }
    }

    /// Sweeps whose firings are at most `step` apart in azimuth (hundredths of a degree), as a
    /// sensor's columns are: a stream that starts within a step past the cut starts a whole
    /// sweep at once, and one that ends within a step before it ends one
    /// ([`finish`](Self::finish)), with no crossing needed.
    pub fn whole_within(mut self, step: u32) -> Self {
        self.whole_within = step.min(18_000);
        self
    }

    /// A packet begins at `time_s`; the sensor sends one every `period_s`. Counts the packets
    /// missing since the last one.
    pub fn packet(&mut self, time_s: f64, period_s: f64) {
        if let Some(last) = self.last_packet {
            let dt = time_s - last;
            if !(0.0..=MAX_GAP_S).contains(&dt) {
                self.time_jumps += 1;
                // The sweep being filled is dropped even if whole: its end's time is in doubt.
                if let Some(s) = self.current.take() {
                    self.partial_firings += s.points.len() as u64;
                }
                self.last = None;
                self.last_packet = Some(time_s);
                return;
            }
            let missing = (dt / period_s).round() - 1.0;
            if missing >= 1.0 && missing.is_finite() {
                let n = missing.min(f64::from(u32::MAX)) as u32;
                self.gaps += u64::from(n);
                if let Some(s) = &mut self.current {
                    s.gaps = s.gaps.saturating_add(n);
                }
            }
        }
        self.last_packet = Some(time_s);
    }

    /// Adds a firing at `azimuth` (hundredths of a degree); returns the sweep it completed,
    /// if it starts a new one.
    pub fn push(&mut self, point: Point, time_s: f64, azimuth: u16) -> Option<Sweep> {
        let (azimuth, cut) = (u32::from(azimuth), u32::from(self.cut));
        let past = if azimuth >= cut {
            azimuth - cut
        } else {
            azimuth + 36_000 - cut
        };
        // A crossing: the azimuth past the cut falls back by more than half a turn.
        let crossed = self.last.is_some_and(|last| past + 18_000 < last);
        let starts = self.last.is_none() && self.current.is_none() && past < self.whole_within;
        self.last = Some(past);
        if starts {
            self.current = Some(Sweep::default());
        }
        let done = if crossed {
            // The next sweep is about as long as the last one: room for it at once.
            let room = self
                .current
                .as_ref()
                .map_or(0, |s| s.points.len() + s.points.len() / 8);
            self.current.replace(Sweep {
                points: Vec::with_capacity(room),
                times: Vec::with_capacity(room),
                gaps: 0,
            })
        } else {
            None
        };
        match &mut self.current {
            Some(s) => {
                s.points.push(point);
                s.times.push(time_s);
            }
            None => self.partial_firings += 1,
        }
        done.filter(|s| !s.points.is_empty())
    }

    /// Ends the stream: the sweep being filled, if its last firing is within
    /// [`whole_within`](Self::whole_within) of the cut; otherwise it is a part turn, counted
    /// and dropped.
    pub fn finish(&mut self) -> Option<Sweep> {
        let whole = self
            .last
            .is_some_and(|last| self.whole_within > 0 && last + self.whole_within >= 36_000);
        self.last = None;
        let s = self.current.take()?;
        if whole && !s.points.is_empty() {
            return Some(s);
        }
        self.partial_firings += s.points.len() as u64;
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Firings every 1 degree from `from` for `n` degrees, one a millisecond.
    fn turn(s: &mut Sweeps, from: u32, n: u32, out: &mut Vec<Sweep>) {
        for k in 0..n {
            let az = ((from + k) % 360) * 100;
            let t = f64::from(from + k) * 1e-3;
            if let Some(done) = s.push([k as f32, 0.0, 0.0], t, az as u16) {
                out.push(done);
            }
        }
    }

    #[test]
    fn sweeps_run_from_cut_to_cut_and_part_turns_are_counted() {
        let mut s = Sweeps::new(90.0);
        let mut out = Vec::new();
        // From 10 degrees, three turns and a bit.
        turn(&mut s, 10, 3 * 360 + 45, &mut out);
        s.finish();
        assert_eq!(out.len(), 2);
        for sweep in &out {
            assert_eq!(sweep.points.len(), 360);
        }
        // 80 degrees before the first crossing, 325 after the last one.
        assert_eq!(s.partial_firings, 80 + 325);
        assert!((out[0].stamp().unwrap() - (0.090 + 0.449) / 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_stream_that_starts_and_ends_at_the_cut_is_whole_when_its_steps_say_so() {
        // Two turns of firings 1 degree apart, from the cut itself to 1 degree before it.
        for (step, sweeps, partial) in [(0, 0, 720), (101, 2, 0)] {
            let mut s = Sweeps::new(10.0).whole_within(step);
            let mut out = Vec::new();
            turn(&mut s, 10, 2 * 360, &mut out);
            out.extend(s.finish());
            assert_eq!(
                (out.len(), s.partial_firings),
                (sweeps, partial),
                "step {step}"
            );
        }
        // One degree short of the second turn's end: that turn is a part turn.
        let mut s = Sweeps::new(10.0).whole_within(101);
        let mut out = Vec::new();
        turn(&mut s, 10, 2 * 360 - 1, &mut out);
        out.extend(s.finish());
        assert_eq!((out.len(), s.partial_firings), (1, 359));
    }

    #[test]
    fn a_missing_packet_is_a_counted_gap() {
        let mut s = Sweeps::new(0.0);
        s.packet(0.0, 0.001);
        s.packet(0.001, 0.001);
        s.packet(0.004, 0.001);
        assert_eq!(s.gaps, 2);
        // A jump back in time, or of over a second: no gap, a jump.
        s.packet(0.002, 0.001);
        s.packet(5.0, 0.001);
        assert_eq!((s.gaps, s.time_jumps), (2, 2));
    }
}
