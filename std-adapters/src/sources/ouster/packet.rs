//! The byte layout of an Ouster lidar packet, by profile, as Ouster's sensor documentation
//! gives it ("Lidar Data Packet Format").
//!
//! A legacy packet is its columns alone, each a 16-byte header (timestamp in nanoseconds,
//! measurement id, frame id, encoder count), a 12-byte block a beam and a 4-byte status at the
//! end. Every other profile has a 32-byte packet header (packet type, frame id, ...), columns
//! of a 12-byte header (timestamp, measurement id, status) and the profile's block a beam, and
//! a 32-byte footer. A column is valid when bit 0 of its status is set. Ranges are
//! millimetres: 20 bits (legacy), 19 bits (the `RNG19` profiles) or 15 bits counting 8 mm
//! (the `RNG15` low-data-rate profiles). Little-endian throughout.
//!
//! No `std`, no allocation: firmware could use it as it is.

/// A lidar packet profile (`udp_profile_lidar`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// Firmware 1.x and 2.x's default.
    Legacy,
    /// One return: 19-bit range, reflectivity, signal, near-infrared.
    Rng19,
    /// Two returns of 19-bit range, reflectivity and signal, and near-infrared.
    Rng19Dual,
    /// Low data rate: 15-bit range in 8 mm, reflectivity, near-infrared.
    Rng15,
    /// Low data rate, two returns.
    Rng15Dual,
}

impl Profile {
    /// Every profile decoded.
    pub const ALL: [Profile; 5] = [
        Profile::Legacy,
        Profile::Rng19,
        Profile::Rng19Dual,
        Profile::Rng15,
        Profile::Rng15Dual,
    ];

    /// The name the sensor's metadata gives it.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Legacy => "LEGACY",
            Profile::Rng19 => "RNG19_RFL8_SIG16_NIR16",
            Profile::Rng19Dual => "RNG19_RFL8_SIG16_NIR16_DUAL",
            Profile::Rng15 => "RNG15_RFL8_NIR8",
            Profile::Rng15Dual => "RNG15_RFL8_NIR8_DUAL",
        }
    }

    /// The profile of that name.
    pub fn named(name: &str) -> Option<Profile> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Bytes of one beam's block.
    pub fn block_bytes(self) -> usize {
        match self {
            Profile::Legacy | Profile::Rng19 => 12,
            Profile::Rng19Dual => 16,
            Profile::Rng15 => 4,
            Profile::Rng15Dual => 8,
        }
    }

    /// Returns a beam reports.
    pub fn returns(self) -> usize {
        match self {
            Profile::Rng19Dual | Profile::Rng15Dual => 2,
            _ => 1,
        }
    }

    /// Return `r`'s range (millimetres; 0: none) from a beam's block.
    pub fn range_mm(self, block: &[u8], r: usize) -> u32 {
        let u32_at = |o: usize| {
            block
                .get(o..o + 4)
                .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        };
        let u16_at = |o: usize| {
            block
                .get(o..o + 2)
                .map_or(0, |b| u32::from(u16::from_le_bytes([b[0], b[1]])))
        };
        match (self, r) {
            (Profile::Legacy, 0) => u32_at(0) & 0xF_FFFF,
            (Profile::Rng19, 0) | (Profile::Rng19Dual, 0) => u32_at(0) & 0x7_FFFF,
            (Profile::Rng19Dual, 1) => u32_at(4) & 0x7_FFFF,
            (Profile::Rng15, 0) | (Profile::Rng15Dual, 0) => (u16_at(0) & 0x7FFF) << 3,
            (Profile::Rng15Dual, 1) => (u16_at(4) & 0x7FFF) << 3,
            _ => 0,
        }
    }
}

/// A lidar packet's shape: its profile and size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// The profile.
    pub profile: Profile,
    /// Columns a packet.
    pub columns: usize,
    /// Beams a column.
    pub beams: usize,
}

/// One column's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ColumnHeader {
    /// When the column fired (nanoseconds, the sensor's clock).
    pub timestamp_ns: u64,
    /// Which column of the turn (0 to the columns a turn less one).
    pub measurement_id: u16,
    /// Whether the sensor filled it (outside the column window, or not measured: not).
    pub valid: bool,
}

impl Layout {
    fn packet_header(self) -> usize {
        if self.profile == Profile::Legacy {
            0
        } else {
            32
        }
    }

    fn column_header(self) -> usize {
        if self.profile == Profile::Legacy {
            16
        } else {
            12
        }
    }

    /// Bytes of a column.
    pub fn column_bytes(self) -> usize {
        let footer = if self.profile == Profile::Legacy {
            4
        } else {
            0
        };
        self.column_header() + self.beams * self.profile.block_bytes() + footer
    }

    /// Bytes of a packet.
    pub fn packet_bytes(self) -> usize {
        let footer = if self.profile == Profile::Legacy {
            0
        } else {
            32
        };
        self.packet_header() + self.columns * self.column_bytes() + footer
    }

    /// The packet type a profiled packet's header holds (1: lidar data); `None` for legacy
    /// packets, which have no header.
    pub fn packet_type(self, packet: &[u8]) -> Option<u16> {
        (self.profile != Profile::Legacy)
            .then(|| packet.get(..2).map(|b| u16::from_le_bytes([b[0], b[1]])))
            .flatten()
    }

    /// Column `c` of `packet` (a packet of [`packet_bytes`](Self::packet_bytes)): its header
    /// and its beams' blocks, one after the other.
    pub fn column(self, packet: &[u8], c: usize) -> Option<(ColumnHeader, &[u8])> {
        let start = self.packet_header() + c * self.column_bytes();
        let col = packet.get(start..start + self.column_bytes())?;
        let timestamp_ns = u64::from_le_bytes(col[..8].try_into().ok()?);
        let measurement_id = u16::from_le_bytes([col[8], col[9]]);
        let header = self.column_header();
        let blocks_end = header + self.beams * self.profile.block_bytes();
        let valid = if self.profile == Profile::Legacy {
            col[blocks_end] & 1 == 1
        } else {
            col[10] & 1 == 1
        };
        Some((
            ColumnHeader {
                timestamp_ns,
                measurement_id,
                valid,
            },
            &col[header..blocks_end],
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_sizes_are_the_documented_ones() {
        let size = |profile, beams| {
            Layout {
                profile,
                columns: 16,
                beams,
            }
            .packet_bytes()
        };
        // Ouster's documentation: a legacy OS-1-64 packet is 12 608 bytes; profiled ones are
        // 64 bytes of header and footer and 12 a column more than their blocks.
        assert_eq!(size(Profile::Legacy, 64), 12_608);
        assert_eq!(size(Profile::Legacy, 32), 6_464);
        assert_eq!(size(Profile::Rng19, 128), 64 + 16 * (12 + 128 * 12));
        assert_eq!(size(Profile::Rng19Dual, 32), 64 + 16 * (12 + 32 * 16));
        assert_eq!(size(Profile::Rng15, 128), 8_448);
    }

    #[test]
    fn ranges_are_read_by_the_profiles_bit_widths() {
        let block = [
            0xFF, 0xFF, 0xFF, 0xFF, 0x34, 0x12, 0xF3, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0,
        ];
        assert_eq!(Profile::Legacy.range_mm(&block, 0), 0xF_FFFF);
        assert_eq!(Profile::Rng19.range_mm(&block, 0), 0x7_FFFF);
        assert_eq!(Profile::Rng19Dual.range_mm(&block, 1), 0x3_1234);
        assert_eq!(Profile::Rng15.range_mm(&block, 0), 0x7FFF * 8);
        assert_eq!(Profile::Rng15Dual.range_mm(&block, 1), 0x1234 * 8);
        // A short block reads as no return, never a panic.
        assert_eq!(Profile::Rng19Dual.range_mm(&block[..6], 1), 0);
        assert_eq!(Profile::Rng19.range_mm(&block, 1), 0);
    }
}
