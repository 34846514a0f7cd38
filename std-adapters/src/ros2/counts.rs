//! What the node's inputs counted ([`Counts`]): every message on `points` received, then
//! refused, dropped whole or handed to the run; the IMU's readings; the requests. Shared by
//! the listening thread, `/diagnostics`, `report.json` and the closing line, so that the four
//! agree.

use serde::Serialize;

/// What the node's inputs counted, for `diagnostics` and `report.json`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Counts {
    /// Messages taken on `points`.
    pub received: u64,
    /// Scans handed to the run.
    pub queued: u64,
    /// Scans dropped whole because the run was behind.
    pub dropped: u64,
    /// Messages that were not scans.
    pub refused: u64,
    /// The last refusal: topic, stamp and reason.
    pub last_refused: Option<String>,
    /// Poses taken on `initialpose`.
    pub initial_poses: u64,
    /// Readings taken on `imu`.
    pub imu_readings: u64,
    /// Readings refused (a number not finite) or dropped (more than [`IMU_KEPT`](crate::ros2::listen::IMU_KEPT) waiting).
    pub imu_dropped: u64,
    /// Scans handed to the run before the IMU's readings covered their sweep: the wait
    /// (`imu_wait`) ran out.
    pub imu_late: u64,
    /// Map saves asked for on `~/save_map`.
    pub save_requests: u64,
    /// The latest `/clock` (seconds), when `use_sim_time` is set.
    pub clock_s: Option<f64>,
    /// The scans' frame: the first scan's (or `lidar_frame`).
    pub scans_frame: Option<String>,
    /// The first IMU reading's frame (`header.frame_id`), for its place on the robot.
    pub imu_frame: Option<String>,
}

impl Counts {
    /// The closing line of a node's run: what came on `points` (the topic) and what became of
    /// it, with the run's own counts of frames `used` and `skipped` (read but not used): every
    /// message is received, then refused (not a scan), dropped whole (the run was behind) or
    /// handed to the run; the IMU's part when readings came.
    pub fn closing_line(&self, points: &str, used: usize, skipped: usize) -> String {
        let mut line = format!(
            "{points}: {} message(s) received: {used} scan(s) used, {skipped} skipped, {} \
             dropped whole (the pipeline was behind), {} refused (not scans)",
            self.received, self.dropped, self.refused
        );
        if self.imu_readings > 0 {
            line += &format!(
                "; IMU: {} reading(s), {} dropped, {} scan(s) ran before the readings covered \
                 their sweep",
                self.imu_readings, self.imu_dropped, self.imu_late
            );
        }
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closing_line_counts_every_message() {
        let mut c = Counts {
            received: 120,
            queued: 71,
            dropped: 47,
            refused: 2,
            ..Counts::default()
        };
        assert_eq!(
            c.closing_line("/points", 70, 1),
            "/points: 120 message(s) received: 70 scan(s) used, 1 skipped, 47 dropped whole \
             (the pipeline was behind), 2 refused (not scans)"
        );
        (c.imu_readings, c.imu_dropped, c.imu_late) = (2400, 3, 5);
        assert!(c.closing_line("/points", 70, 1).ends_with(
            "; IMU: 2400 reading(s), 3 dropped, 5 scan(s) ran before the readings covered their \
             sweep"
        ));
    }
}
