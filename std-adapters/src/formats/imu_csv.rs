//! IMU readings as a CSV in EuRoC's `imu0/data.csv` layout: a header line starting with `#`
//! (`#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x
//! [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]`), then one reading a line: the stamp in
//! integer nanoseconds, the gyro (rad/s) and the accelerometer (m/s²), in the IMU's axes.
//!
//! [`parse`] keeps every line it can read; a line it cannot is skipped and named (its number
//! and why) in [`ImuCsv::skipped`]. Readings stay in the file's order: the run's track refuses
//! and counts those out of order. Blank lines and further `#` lines are passed over.

use crate::io::error::FileError;
use slamesh_core::imu::ImuSample as ImuReading;
use std::path::Path;

/// The readings of one file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuCsv {
    /// Readings in file order (stamps in seconds).
    pub readings: Vec<ImuReading>,
    /// Lines not read: `line N: reason`.
    pub skipped: Vec<String>,
}

/// Reads a file (see the module docs); an error only when the file cannot be read or holds
/// no reading at all.
pub fn read(path: &Path) -> Result<ImuCsv, FileError> {
    let bytes =
        std::fs::read(path).map_err(|e| FileError::at(path, format!("cannot read: {e}")))?;
    let csv = parse(&bytes);
    if csv.readings.is_empty() {
        let why = csv
            .skipped
            .first()
            .map_or("it is empty".to_string(), |s| s.clone());
        return Err(FileError::at(path, format!("no IMU reading in it: {why}")));
    }
    Ok(csv)
}

/// Parses the text of a file (bytes that are not UTF-8 spoil only their lines).
pub fn parse(bytes: &[u8]) -> ImuCsv {
    let mut csv = ImuCsv::default();
    for (k, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let Ok(line) = std::str::from_utf8(line) else {
            csv.skipped.push(format!("line {}: not UTF-8 text", k + 1));
            continue;
        };
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        match reading(line) {
            Ok(r) => csv.readings.push(r),
            // The first line may be a header without its `#`.
            Err(_) if k == 0 && line.starts_with(|c: char| c.is_ascii_alphabetic()) => {}
            Err(why) => csv.skipped.push(format!("line {}: {why}", k + 1)),
        }
    }
    csv
}

/// One line: seven comma-separated fields.
fn reading(line: &str) -> Result<ImuReading, String> {
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    if fields.len() != 7 {
        return Err(format!(
            "{} fields, 7 expected (stamp, gyro x y z, accelerometer x y z)",
            fields.len()
        ));
    }
    let ns: i64 = fields[0]
        .parse()
        .map_err(|_| format!("stamp {:?} is not a whole number of nanoseconds", fields[0]))?;
    let mut v = [0.0; 6];
    for (slot, f) in v.iter_mut().zip(&fields[1..]) {
        *slot = f
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{f:?} is not a finite number"))?;
    }
    Ok(ImuReading {
        stamp: ns as f64 * 1e-9,
        gyro: [v[0], v[1], v[2]],
        accel: [v[3], v[4], v[5]],
    })
}

/// `readings` as a file in this layout, stamps rounded to the nanosecond (what [`parse`]
/// reads back).
pub fn encode(readings: &[ImuReading]) -> String {
    use std::fmt::Write as _;
    let mut csv = String::from(
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],\
         a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n",
    );
    for r in readings {
        let [gx, gy, gz] = r.gyro;
        let [ax, ay, az] = r.accel;
        let ns = (r.stamp * 1e9).round() as i64;
        // Writing to a String cannot fail.
        let _ = writeln!(csv, "{ns},{gx:e},{gy:e},{gz:e},{ax:e},{ay:e},{az:e}");
    }
    csv
}

/// The readings file that goes with a folder of scans, if there is one: `imu0/data.csv` or
/// `imu.csv` in the folder, or beside it.
pub fn beside(folder: &Path) -> Option<std::path::PathBuf> {
    let dirs = [Some(folder), folder.parent()];
    dirs.into_iter()
        .flatten()
        .flat_map(|d| [d.join("imu0").join("data.csv"), d.join("imu.csv")])
        .find(|p| p.is_file())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_euroc_lines_and_names_the_bad_ones() {
        let text = "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],\
                    a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n\
                    1403636579758555392,-0.099134701513277898,0.14032447186034408,0.020246742334979833,8.1476917083333333,-0.37592158333333331,-2.4026292499999999\n\
                    1403636579763555584, 0.1, 0.2, 0.3, 0.4, 0.5, 9.8\r\n\
                    \n\
                    12,1,2,3\n\
                    13,1,2,3,4,5,nan\n\
                    x,1,2,3,4,5,6\n";
        let csv = parse(text.as_bytes());
        assert_eq!(csv.readings.len(), 2);
        let r = csv.readings[0];
        assert!((r.stamp - 1_403_636_579.758_555_4).abs() < 1e-6);
        assert_eq!(r.gyro[1], 0.14032447186034408);
        assert_eq!(r.accel[2], "-2.4026292499999999".parse::<f64>().unwrap());
        assert_eq!(csv.readings[1].accel, [0.4, 0.5, 9.8]);
        assert_eq!(csv.skipped.len(), 3, "{:?}", csv.skipped);
        assert!(csv.skipped[0].starts_with("line 5: 4 fields"));
        assert!(csv.skipped[1].contains("\"nan\" is not a finite number"));
        assert!(csv.skipped[2].contains("not a whole number"));
    }

    #[test]
    fn encoded_readings_read_back() {
        let readings = [
            ImuReading {
                stamp: 1_733_560_000.005,
                gyro: [0.1, -0.25, 3e-7],
                accel: [0.0, 9.81, -1.5e3],
            },
            ImuReading {
                stamp: 0.0,
                gyro: [0.0; 3],
                accel: [1.0; 3],
            },
        ];
        let csv = parse(encode(&readings).as_bytes());
        assert!(csv.skipped.is_empty(), "{:?}", csv.skipped);
        assert_eq!(csv.readings.len(), 2);
        for (read, given) in csv.readings.iter().zip(&readings) {
            assert_eq!((read.gyro, read.accel), (given.gyro, given.accel));
            // Whole nanoseconds, read back as f64 seconds: an epoch stamp to some 2e-7 s.
            assert!((read.stamp - given.stamp).abs() < 1e-6);
        }
    }

    #[test]
    fn an_empty_or_unreadable_file_is_an_error_that_names_it() {
        let dir = crate::test_support::scratch_dir("imu-csv");
        let p = dir.join("imu.csv");
        std::fs::write(&p, "#timestamp\n1,2,3\n").unwrap();
        let e = read(&p).unwrap_err().to_string();
        assert!(
            e.contains("imu.csv") && e.contains("line 2: 3 fields"),
            "{e}"
        );
        assert!(read(&dir.join("none.csv")).is_err());
        assert_eq!(beside(&dir), Some(p));
    }
}
