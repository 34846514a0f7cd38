//! A sensor's packet stream made sweeps, wherever the packets come from (a capture file,
//! [`crate::io::replay`]; a socket, [`crate::io::live`]): which datagrams are the sensor's
//! data, which sensor it is, each packet decoded and its firings cut into turns.

use crate::io::sweep::{Sweep, Sweeps};
use crate::io::velodyne::{self, tables::Model, Decoder, POSITION_PACKET_BYTES};
use serde::Serialize;

/// What a stream counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StreamStats {
    /// The sensor's data packets decoded.
    pub packets: u64,
    /// Its packets refused as damaged (a bad flag, azimuth or byte).
    pub bad_packets: u64,
    /// Packets missing between those decoded.
    pub gaps: u64,
    /// Firings in part turns at the ends, or cut off by a jump in time (no sweep).
    pub partial_firings: u64,
    /// Jumps in the packets' time ([`crate::io::sweep::MAX_GAP_S`]).
    pub time_jumps: u64,
}

/// The sensor names `--sensor` takes.
pub fn sensor_names() -> Vec<&'static str> {
    velodyne::tables::MODELS.iter().map(|m| m.flag).collect()
}

/// The model `--sensor` names; an error lists the names.
pub fn named(sensor: &str) -> Result<&'static Model, String> {
    velodyne::model_named(sensor).ok_or_else(|| {
        format!(
            "--sensor {sensor}: not one of {}",
            sensor_names().join(", ")
        )
    })
}

/// What a datagram says of the sensor: `Ok(Some(model))` for a data packet of a model this
/// reader decodes (the one `named`, when given), `Ok(None)` for anything else, and an error
/// for a sensor's packets that cannot be read (another model than named, an HDL-64E, a model
/// not decoded).
pub fn identify(
    payload: &[u8],
    named: Option<&'static Model>,
) -> Result<Option<&'static Model>, String> {
    if let Some(product) = velodyne::sniff(payload) {
        return match (named, velodyne::model_of(product)) {
            (Some(n), Some(f)) if n.product_id != f.product_id => Err(format!(
                "--sensor {}: the packets are a {}'s",
                n.flag, f.name
            )),
            (Some(m), _) | (None, Some(m)) => Ok(Some(m)),
            (None, None) => Err(format!(
                "Velodyne data packets of product {product:#04x}, a model this reader does not \
                 decode (it reads {}); name one with --sensor if it is one of them",
                sensor_names().join(", ")
            )),
        };
    }
    if payload.len() == velodyne::DATA_PACKET_BYTES
        && payload.get(..2) == Some(&[0xff, 0xee][..])
        && payload.get(100..102) == Some(&[0xff, 0xdd][..])
    {
        // FF EE then FF DD blocks: an HDL-64E.
        return Err(
            "HDL-64E packets: they need the unit's own calibration, which this reader \
                    does not take yet"
                .to_string(),
        );
    }
    Ok(None)
}

/// One sensor's packets to sweeps.
#[derive(Debug)]
pub struct SensorStream {
    decoder: Decoder,
    port: u16,
    sweeps: Sweeps,
    stats: StreamStats,
}

impl SensorStream {
    /// The stream of `model`'s data packets sent to `port`, cut at `cut_deg` degrees.
    pub fn new(model: &'static Model, port: u16, cut_deg: f64) -> Self {
        Self {
            decoder: Decoder::new(model),
            port,
            sweeps: Sweeps::new(cut_deg),
            stats: StreamStats::default(),
        }
    }

    /// The sensor's model name.
    pub fn sensor(&self) -> &'static str {
        self.decoder.model().name
    }

    /// A datagram sent to `port`, received at `time_s` (any clock within half an hour of the
    /// sensor's): the sweep it completed, if it did. Other ports' datagrams and position
    /// packets are passed over.
    pub fn datagram(&mut self, port: u16, payload: &[u8], time_s: f64) -> Option<Sweep> {
        if port != self.port || payload.len() == POSITION_PACKET_BYTES {
            return None;
        }
        let Some(t) = velodyne::packet_time(payload, time_s) else {
            self.stats.bad_packets += 1;
            return None;
        };
        let mut done = None;
        let sweeps = &mut self.sweeps;
        match self.decoder.decode(payload, t, |f| {
            if let Some(s) = sweeps.push(f.point, f.time_s, f.azimuth) {
                done = Some(s);
            }
        }) {
            Ok(mode) => {
                self.stats.packets += 1;
                self.sweeps.packet(t, self.decoder.packet_period_s(mode));
            }
            Err(_) => self.stats.bad_packets += 1,
        }
        done
    }

    /// What it counted so far (the part turn being filled counted as partial only once
    /// [`finish`](Self::finish)ed).
    pub fn stats(&self) -> StreamStats {
        StreamStats {
            gaps: self.sweeps.gaps,
            partial_firings: self.sweeps.partial_firings,
            time_jumps: self.sweeps.time_jumps,
            ..self.stats
        }
    }

    /// Ends the stream (the turn being filled is a part turn).
    pub fn finish(&mut self) -> StreamStats {
        self.sweeps.finish();
        self.stats()
    }
}
