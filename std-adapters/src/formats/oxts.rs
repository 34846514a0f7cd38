//! KITTI raw's OXTS packets and timestamps, as the dataset ships them: `oxts/data/*.txt`, one
//! packet a file (30 numbers on a line: position, attitude, velocities, accelerations, angular
//! rates, accuracies and modes, KITTI's `dataformat.txt`), and `oxts/timestamps.txt`, one
//! `YYYY-MM-DD HH:MM:SS.nnnnnnnnn` a line, the same clock as `velodyne_points/timestamps*.txt`.
//!
//! A packet gives an IMU reading in the vehicle's own axes (x forward, y left, z up): the
//! angular rates `wx wy wz` (fields 18-20, rad/s) and the accelerations `ax ay az` (fields
//! 12-14, m/s², the specific force, gravity in it: about 9.8 up at rest). The `f l u` fields
//! are the same in a frame levelled on the earth's tangent plane, not the body's, and are not
//! read. The synced sets hold 10 packets a second, too slow for an IMU prior (the run says so
//! and goes on without it); the extracted sets 100.
//!
//! [`read`] keeps every packet it can read; one it cannot is skipped and named (its file and
//! why) in [`Oxts::skipped`]. Times are seconds since 1970 as written (no time zone).

use crate::io::error::FileError;
use slamesh_core::imu::ImuSample as ImuReading;
use std::fmt;
use std::path::Path;

/// Numbers on a packet's line.
pub const FIELDS: usize = 30;

/// The accelerations' first field (`ax`), counted from 0.
const ACCEL: usize = 11;

/// The angular rates' first field (`wx`), counted from 0.
const GYRO: usize = 17;

/// The readings of an `oxts` folder.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Oxts {
    /// Readings in the packets' order (stamps in seconds).
    pub readings: Vec<ImuReading>,
    /// Packets not read: `FILE: reason`.
    pub skipped: Vec<String>,
}

/// Why a packet's line or a timestamp could not be read.
#[derive(Debug, Clone, PartialEq)]
pub enum BadPacket {
    /// Fewer numbers than [`FIELDS`].
    TooFew {
        /// Numbers found.
        found: usize,
    },
    /// A field is not a number, or not finite where the reading needs it.
    NotANumber {
        /// The field (counted from 1).
        field: usize,
    },
    /// A timestamp is not `YYYY-MM-DD HH:MM:SS.fraction`.
    BadTime(String),
}

impl fmt::Display for BadPacket {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BadPacket::TooFew { found } => {
                write!(
                    f,
                    "{found} numbers on its line, an OXTS packet has {FIELDS}"
                )
            }
            BadPacket::NotANumber { field } => write!(f, "field {field} is not a finite number"),
            BadPacket::BadTime(t) => {
                write!(f, "{t:?} is not a time (YYYY-MM-DD HH:MM:SS.fraction)")
            }
        }
    }
}

/// The gyro (rad/s) and the specific force (m/s²) of one packet's text, in the vehicle's axes.
pub fn parse_packet(text: &str) -> Result<([f64; 3], [f64; 3]), BadPacket> {
    let words: Vec<&str> = text.split_whitespace().collect();
    if words.len() < FIELDS {
        return Err(BadPacket::TooFew { found: words.len() });
    }
    let number = |k: usize| {
        words[k]
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or(BadPacket::NotANumber { field: k + 1 })
    };
    let three = |k: usize| -> Result<[f64; 3], BadPacket> {
        Ok([number(k)?, number(k + 1)?, number(k + 2)?])
    };
    Ok((three(GYRO)?, three(ACCEL)?))
}

/// One packet's line with `gyro` and `accel` in their fields and zeros elsewhere (what the
/// simulator writes; KITTI's other fields are not read).
pub fn encode_packet(gyro: [f64; 3], accel: [f64; 3]) -> String {
    let mut v = [0.0; FIELDS];
    v[GYRO..GYRO + 3].copy_from_slice(&gyro);
    v[ACCEL..ACCEL + 3].copy_from_slice(&accel);
    let words: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
    words.join(" ") + "\n"
}

/// Seconds since 1970 of a KITTI timestamp (`2011-09-26 13:02:25.964389445`).
pub fn parse_time(text: &str) -> Result<f64, BadPacket> {
    let bad = || BadPacket::BadTime(text.to_string());
    let (date, time) = text.trim().split_once(' ').ok_or_else(bad)?;
    let ymd: Vec<i64> = date
        .split('-')
        .map(|s| s.parse().ok())
        .collect::<Option<_>>()
        .ok_or_else(bad)?;
    let [y, m, d] = ymd[..] else {
        return Err(bad());
    };
    let hms: Vec<&str> = time.split(':').collect();
    let [h, min, s] = hms[..] else {
        return Err(bad());
    };
    let (h, min): (i64, i64) = (
        h.parse().map_err(|_| bad())?,
        min.parse().map_err(|_| bad())?,
    );
    let (whole, fraction) = s.split_once('.').unwrap_or((s, "0"));
    if fraction.is_empty() || !fraction.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let whole: i64 = whole.parse().map_err(|_| bad())?;
    let digits = fraction.len().min(9);
    let nanos: i64 = fraction[..digits].parse().map_err(|_| bad())?;
    let nanos = nanos * 10i64.pow((9 - digits) as u32);
    let in_range =
        (1..=12).contains(&m) && (1..=31).contains(&d) && h < 24 && min < 60 && whole < 61;
    if !in_range || h < 0 || min < 0 || whole < 0 || !(0..=9999).contains(&y) {
        return Err(bad());
    }
    let seconds = days_from_civil(y, m, d) * 86_400 + h * 3_600 + min * 60 + whole;
    Ok(seconds as f64 + nanos as f64 * 1e-9)
}

/// A KITTI timestamp of `t` seconds since 1970 (what [`parse_time`] reads back).
pub fn format_time(t: f64) -> String {
    let whole = t.floor() as i64;
    let nanos = ((t - whole as f64) * 1e9).round().min(999_999_999.0) as i64;
    let (days, rest) = (whole.div_euclid(86_400), whole.rem_euclid(86_400));
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{nanos:09}",
        rest / 3_600,
        rest / 60 % 60,
        rest % 60
    )
}

/// Days since 1970-01-01 of a date in the proleptic Gregorian calendar.
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (m + if m > 2 { -3 } else { 9 }) + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date of a day counted from 1970-01-01 ([`days_from_civil`]'s inverse).
fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// The stamps of a `timestamps.txt` (one a line; blank lines passed over), each line's fault
/// named by its number.
pub fn parse_times(text: &str) -> Result<Vec<f64>, (usize, BadPacket)> {
    (text.lines().enumerate())
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(k, l)| parse_time(l).map_err(|e| (k + 1, e)))
        .collect()
}

/// Reads `timestamps.txt` at `path` ([`parse_times`]), naming the file and line of a fault.
pub fn read_times(path: &Path) -> Result<Vec<f64>, FileError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| FileError::at(path, format!("cannot read: {e}")))?;
    parse_times(&text).map_err(|(line, e)| FileError::at(path, format!("line {line}: {e}")))
}

/// Reads an `oxts` folder: `timestamps.txt` and the packets of `data/` in name order, one
/// stamp a packet. An error when the stamps cannot be read, or they and the packets differ
/// in number, or no packet reads.
pub fn read(oxts: &Path) -> Result<Oxts, FileError> {
    let stamps = read_times(&oxts.join("timestamps.txt"))?;
    let data = oxts.join("data");
    let mut files: Vec<_> = std::fs::read_dir(&data)
        .map_err(|e| FileError::at(&data, format!("cannot read: {e}")))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    files.sort();
    if files.len() != stamps.len() {
        return Err(FileError::at(
            &data,
            format!(
                "{} packets, and timestamps.txt has {} stamps: they must pair one to one",
                files.len(),
                stamps.len()
            ),
        ));
    }
    let mut out = Oxts::default();
    for (file, stamp) in files.iter().zip(stamps) {
        let packet = std::fs::read_to_string(file)
            .map_err(|e| e.to_string())
            .and_then(|t| parse_packet(&t).map_err(|e| e.to_string()));
        match packet {
            Ok((gyro, accel)) => out.readings.push(ImuReading { stamp, gyro, accel }),
            Err(why) => out.skipped.push(format!("{}: {why}", file.display())),
        }
    }
    if out.readings.is_empty() {
        return Err(FileError::at(oxts, "no OXTS packet in it could be read"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A packet laid out as KITTI raw writes one (30 numbers; the values made up for the test).
    const PACKET: &str = "49.015003823272 8.4342971002335 116.43032836914 0.035752 0.00903 \
        -2.6087069803847 -3.3419712040229 8.7112803342804 9.3308253456509 0.11123455008034 \
        0.063148587309811 -0.41212437614754 -0.024002218060196 9.7985396087101 \
        -0.21874010467529 -0.047131843276978 9.8055105934563 0.0089281624706069 \
        -0.029010719298862 0.028713081407143 0.009306926052571 -0.030083853845193 \
        0.027712045950689 0.014059988437355 0.014059988437355 4 10 4 4 0";

    #[test]
    fn a_packet_gives_the_body_axes_rates_and_specific_force() {
        let (gyro, accel) = parse_packet(PACKET).unwrap();
        assert_eq!(
            gyro,
            [0.0089281624706069, -0.029010719298862, 0.028713081407143]
        );
        assert_eq!(
            accel,
            [-0.41212437614754, -0.024002218060196, 9.7985396087101]
        );
        let (g, a) = parse_packet(&encode_packet([0.1, 0.2, 0.3], [1.0, 2.0, 9.8])).unwrap();
        assert_eq!((g, a), ([0.1, 0.2, 0.3], [1.0, 2.0, 9.8]));
        assert_eq!(parse_packet("1 2 3"), Err(BadPacket::TooFew { found: 3 }));
        let bad = PACKET.replacen("0.0089281624706069", "nan", 1);
        assert_eq!(parse_packet(&bad), Err(BadPacket::NotANumber { field: 18 }));
    }

    #[test]
    fn timestamps_read_and_written_back_to_a_microsecond() {
        // Seconds since 1970 in an f64 keep about 0.2 µs at this size.
        let t = parse_time("2011-09-26 13:02:25.964389445").unwrap();
        assert!((t - 1_317_042_145.964_389_4).abs() < 1e-6, "{t}");
        let back = format_time(t);
        assert!(back.starts_with("2011-09-26 13:02:25.964389"), "{back}");
        assert!((parse_time(&back).unwrap() - t).abs() < 1e-6);
        assert_eq!(parse_time("1970-01-01 00:00:00").unwrap(), 0.0);
        assert_eq!(format_time(86_400.5), "1970-01-02 00:00:00.500000000");
        assert_eq!(
            parse_time("2000-02-29 12:00:00.25").unwrap(),
            951_825_600.25
        );
        for bad in [
            "",
            "2011-09-26",
            "2011-13-01 00:00:00",
            "2011-09-26 25:00:00",
            "x y",
            "2011-09-26 1:2",
        ] {
            assert!(
                matches!(parse_time(bad), Err(BadPacket::BadTime(_))),
                "{bad}"
            );
        }
        assert_eq!(
            parse_times("\n2011-09-26 13:02:25.1\nbad\n").unwrap_err().0,
            3
        );
    }

    #[test]
    fn a_folder_pairs_its_packets_with_their_stamps_and_names_the_bad_ones() {
        let dir = std::env::temp_dir().join(format!("slamesh-oxts-{}", std::process::id()));
        let data = dir.join("data");
        std::fs::create_dir_all(&data).unwrap();
        std::fs::write(data.join("0000000000.txt"), PACKET).unwrap();
        std::fs::write(data.join("0000000001.txt"), "1 2 3").unwrap();
        std::fs::write(
            dir.join("timestamps.txt"),
            "2011-09-26 13:02:25.0\n2011-09-26 13:02:25.01\n",
        )
        .unwrap();
        let oxts = read(&dir).unwrap();
        assert_eq!(oxts.readings.len(), 1);
        assert!(
            oxts.skipped[0].contains("0000000001.txt: 3 numbers"),
            "{:?}",
            oxts.skipped
        );
        std::fs::write(dir.join("timestamps.txt"), "2011-09-26 13:02:25.0\n").unwrap();
        let e = read(&dir).unwrap_err().to_string();
        assert!(e.contains("2 packets, and timestamps.txt has 1"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
