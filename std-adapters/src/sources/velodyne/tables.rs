//! The factory tables of the Velodyne models: each laser's elevation, azimuth offset and
//! vertical offset, the distance unit, and when each channel of a data block fires.
//!
//! Sources, Velodyne's own documents: the VLP-16 user manual (63-9243, laser angles and the
//! firing timing of chapter 9), the Puck Hi-Res data sheet and envelope drawing (86-0129), the
//! VLP-32C user manual (63-9325, its laser table of elevations and azimuth offsets and its
//! firing timing), the HDL-32E user manual and packet-structure note (63-9277: elevations,
//! 1.152 us a firing, 46.08 us a cycle) and its envelope drawing (86-0106: each laser's
//! vertical offset from the sensor's origin). Where a model's drawing gives no vertical
//! offsets, they follow from the beams' common focal point: `focal * tan(-elevation)`, with the
//! focal distance of the model's drawing.

/// One laser: where its beam points and where it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Laser {
    /// Elevation (degrees, up positive).
    pub elevation_deg: f64,
    /// Azimuth offset (degrees), subtracted from the block's azimuth as the manuals define it.
    pub azimuth_offset_deg: f64,
    /// Height of the beam's origin above the sensor's origin (metres); for a model with a
    /// focal distance, derived from it instead ([`Model::vertical_offset_m`]).
    pub vertical_offset_m: f64,
}

/// When channel `j` of a block fires, relative to the packet's first firing (microseconds),
/// for the `k`-th distinct firing block of the packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timing {
    /// Two sequences of 16 lasers a block, 2.304 us apart, a sequence every 55.296 us.
    Vlp16,
    /// 32 lasers a block in pairs, a pair every 2.304 us, a block every 55.296 us.
    Vlp32c,
    /// 32 lasers a block, 1.152 us apart, a block every 46.08 us.
    Hdl32e,
}

impl Timing {
    /// The firing time of channel `j` of firing block `k` (microseconds).
    pub fn offset_us(self, k: usize, j: usize) -> f64 {
        match self {
            Timing::Vlp16 => 55.296 * (2 * k + j / 16) as f64 + 2.304 * (j % 16) as f64,
            Timing::Vlp32c => 55.296 * k as f64 + 2.304 * (j / 2) as f64,
            Timing::Hdl32e => 46.08 * k as f64 + 1.152 * j as f64,
        }
    }
}

/// A model: its name, the product byte of its packets, its lasers and units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model {
    /// Its name in messages.
    pub name: &'static str,
    /// The value of `--sensor` that names it.
    pub flag: &'static str,
    /// The packet's last byte for this model.
    pub product_id: u8,
    /// Its lasers, by channel.
    pub lasers: &'static [Laser],
    /// The unit of a raw distance (metres).
    pub distance_unit_m: f64,
    /// When its channels fire.
    pub timing: Timing,
    /// The distance (mm) from the sensor's axis to the point where its beams cross, when its
    /// vertical offsets follow from it.
    pub focal_mm: Option<f64>,
}

const fn laser(elevation_deg: f64, azimuth_offset_deg: f64, vertical_offset_mm: f64) -> Laser {
    Laser {
        elevation_deg,
        azimuth_offset_deg,
        vertical_offset_m: vertical_offset_mm * 1e-3,
    }
}

/// Lasers given as (azimuth offset, elevation), whose vertical offsets follow from the
/// model's focal distance.
macro_rules! focal_lasers {
    ($(($az:expr, $el:expr)),* $(,)?) => {
        [$(laser($el, $az, 0.0)),*]
    };
}

/// The VLP-16: 16 lasers from -15 to +15 degrees, 2 degrees apart, interleaved; a focal
/// distance of 41.91 mm.
pub static VLP16_LASERS: [Laser; 16] = focal_lasers!(
    (0.0, -15.0),
    (0.0, 1.0),
    (0.0, -13.0),
    (0.0, 3.0),
    (0.0, -11.0),
    (0.0, 5.0),
    (0.0, -9.0),
    (0.0, 7.0),
    (0.0, -7.0),
    (0.0, 9.0),
    (0.0, -5.0),
    (0.0, 11.0),
    (0.0, -3.0),
    (0.0, 13.0),
    (0.0, -1.0),
    (0.0, 15.0)
);

/// The Puck Hi-Res: 16 lasers from -10 to +10 degrees, 4/3 degree apart, with the vertical
/// offsets of its drawing.
pub static PUCK_HIRES_LASERS: [Laser; 16] = [
    laser(-10.0, 0.0, 7.4),
    laser(0.667, 0.0, -0.9),
    laser(-8.667, 0.0, 6.5),
    laser(2.0, 0.0, -1.8),
    laser(-7.333, 0.0, 5.5),
    laser(3.333, 0.0, -2.7),
    laser(-6.0, 0.0, 4.6),
    laser(4.667, 0.0, -3.7),
    laser(-4.667, 0.0, 3.7),
    laser(6.0, 0.0, -4.6),
    laser(-3.333, 0.0, 2.7),
    laser(7.333, 0.0, -5.5),
    laser(-2.0, 0.0, 1.8),
    laser(8.667, 0.0, -6.5),
    laser(-0.667, 0.0, 0.9),
    laser(10.0, 0.0, -7.4),
];

/// The VLP-32C: 32 lasers from -25 to +15 degrees, each with its azimuth offset; a focal
/// distance of 42.4 mm.
pub static VLP32C_LASERS: [Laser; 32] = focal_lasers!(
    (-1.4, -25.0),
    (4.2, -1.0),
    (-1.4, -1.667),
    (1.4, -15.639),
    (-1.4, -11.31),
    (1.4, 0.0),
    (-4.2, -0.667),
    (1.4, -8.843),
    (-1.4, -7.254),
    (4.2, 0.333),
    (-1.4, -0.333),
    (1.4, -6.148),
    (-4.2, -5.333),
    (1.4, 1.333),
    (-4.2, 0.667),
    (1.4, -4.0),
    (-1.4, -4.667),
    (4.2, 1.667),
    (-1.4, 1.0),
    (4.2, -3.667),
    (-4.2, -3.333),
    (1.4, 3.333),
    (-1.4, 2.333),
    (1.4, -2.667),
    (-1.4, -3.0),
    (1.4, 7.0),
    (-1.4, 4.667),
    (4.2, -2.333),
    (-4.2, -2.0),
    (1.4, 15.0),
    (-1.4, 10.333),
    (1.4, -1.333)
);

/// The HDL-32E: 32 lasers from -30.67 to +10.67 degrees, 4/3 degree apart, interleaved, with
/// the vertical offsets of its drawing.
pub static HDL32E_LASERS: [Laser; 32] = [
    laser(-30.67, 0.0, 17.17),
    laser(-9.33, 0.0, 4.76),
    laser(-29.33, 0.0, 16.27),
    laser(-8.0, 0.0, 4.07),
    laser(-28.0, 0.0, 15.4),
    laser(-6.67, 0.0, 3.38),
    laser(-26.67, 0.0, 14.54),
    laser(-5.33, 0.0, 2.7),
    laser(-25.33, 0.0, 13.71),
    laser(-4.0, 0.0, 2.02),
    laser(-24.0, 0.0, 12.89),
    laser(-2.67, 0.0, 1.35),
    laser(-22.67, 0.0, 12.09),
    laser(-1.33, 0.0, 0.67),
    laser(-21.33, 0.0, 11.31),
    laser(0.0, 0.0, 0.0),
    laser(-20.0, 0.0, 10.54),
    laser(1.33, 0.0, -0.67),
    laser(-18.67, 0.0, 9.78),
    laser(2.67, 0.0, -1.35),
    laser(-17.33, 0.0, 9.04),
    laser(4.0, 0.0, -2.02),
    laser(-16.0, 0.0, 8.3),
    laser(5.33, 0.0, -2.7),
    laser(-14.67, 0.0, 7.58),
    laser(6.67, 0.0, -3.38),
    laser(-13.33, 0.0, 6.86),
    laser(8.0, 0.0, -4.07),
    laser(-12.0, 0.0, 6.15),
    laser(9.33, 0.0, -4.76),
    laser(-10.67, 0.0, 5.45),
    laser(10.67, 0.0, -5.45),
];

impl Model {
    /// Laser `i`'s vertical offset (metres): from the focal distance when the model has one,
    /// otherwise the table's.
    pub fn vertical_offset_m(&self, i: usize) -> f64 {
        let Some(l) = self.lasers.get(i) else {
            return 0.0;
        };
        match self.focal_mm {
            Some(f) => f * 1e-3 * (-l.elevation_deg.to_radians()).tan(),
            None => l.vertical_offset_m,
        }
    }
}

/// The models this reader decodes.
pub static MODELS: [Model; 4] = [
    Model {
        name: "VLP-16",
        flag: "vlp16",
        product_id: 0x22,
        lasers: &VLP16_LASERS,
        distance_unit_m: 0.002,
        timing: Timing::Vlp16,
        focal_mm: Some(41.91),
    },
    Model {
        name: "Puck Hi-Res",
        flag: "puck-hires",
        product_id: 0x24,
        lasers: &PUCK_HIRES_LASERS,
        distance_unit_m: 0.002,
        timing: Timing::Vlp16,
        focal_mm: None,
    },
    Model {
        name: "VLP-32C",
        flag: "vlp32c",
        product_id: 0x28,
        lasers: &VLP32C_LASERS,
        distance_unit_m: 0.004,
        timing: Timing::Vlp32c,
        focal_mm: Some(42.4),
    },
    Model {
        name: "HDL-32E",
        flag: "hdl32",
        product_id: 0x21,
        lasers: &HDL32E_LASERS,
        distance_unit_m: 0.002,
        timing: Timing::Hdl32e,
        focal_mm: None,
    },
];
