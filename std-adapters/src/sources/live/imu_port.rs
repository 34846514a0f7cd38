//! An Ouster's IMU port, live: the sensor sends its IMU packets to a port of their own (the
//! metadata's `udp_port_imu`, 7503 unless set) beside its lidar port. A thread listens there
//! on the lidar socket's address, decodes each packet into a reading in the sensor frame
//! ([`crate::sources::ouster::imu_packet`]) and keeps it until the lidar thread hands the
//! readings over with the next sweep.
//!
//! It guarantees that it never stops the lidar stream: a port it cannot bind is named and the
//! run goes on without the IMU; at most [`KEPT`] readings wait (the oldest dropped, counted);
//! the thread ends with the stream's stop flag.

use super::{receive, ImuPortStats, LiveStats};
use crate::sources::ouster::imu_packet::ImuPacket;
use crate::sources::ouster::{self, metadata::IMU_PORT};
use slamesh_core::imu::ImuSample;
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Readings waiting for the next sweep.
pub type Readings = Arc<Mutex<VecDeque<ImuSample>>>;

/// The most readings that wait (40 s at an Ouster's 100 Hz).
pub const KEPT: usize = 4096;

/// Listens on `sensor`'s IMU port at `lidar`'s address, unless it is the lidar port (then
/// the lidar thread decodes them): the readings and the thread, or `None` (named) when the
/// port cannot be listened on.
pub fn listen(
    sensor: &Arc<ouster::Sensor>,
    lidar: SocketAddr,
    stop: &Arc<AtomicBool>,
    stats: &Arc<Mutex<LiveStats>>,
) -> Option<(Readings, JoinHandle<()>)> {
    let port = sensor.metadata().udp_port_imu.unwrap_or(IMU_PORT);
    if port == lidar.port() {
        return None;
    }
    let at = SocketAddr::new(lidar.ip(), port);
    let socket = match UdpSocket::bind(at).and_then(|s| {
        s.set_read_timeout(Some(Duration::from_millis(50)))
            .map(|()| s)
    }) {
        Ok(s) => s,
        Err(e) => {
            log::warn!(
                "cannot listen for the Ouster's IMU on {at}: {e}; the run goes on without it"
            );
            return None;
        }
    };
    if let Ok(mut s) = stats.lock() {
        s.imu_port = Some(ImuPortStats {
            port,
            ..ImuPortStats::default()
        });
    }
    let readings: Readings = Arc::default();
    let job = Job {
        socket,
        imu_to_sensor: sensor.metadata().imu_to_sensor,
        readings: readings.clone(),
        stop: stop.clone(),
        stats: stats.clone(),
    };
    let thread = std::thread::Builder::new()
        .name("slamesh-udp-imu".into())
        .spawn(move || job.run());
    match thread {
        Ok(t) => Some((readings, t)),
        Err(e) => {
            log::warn!("cannot start the IMU's listening thread: {e}; the run goes on without it");
            None
        }
    }
}

/// The readings waiting, taken.
pub fn take(readings: &Readings) -> Vec<ImuSample> {
    readings
        .lock()
        .map(|mut r| r.drain(..).collect())
        .unwrap_or_default()
}

struct Job {
    socket: UdpSocket,
    imu_to_sensor: [f64; 16],
    readings: Readings,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<LiveStats>>,
}

impl Job {
    fn run(self) {
        let mut buf = [0u8; 2048];
        while !self.stop.load(Ordering::Relaxed) {
            let n = match receive(&self.socket, &mut buf) {
                Ok(Some(n)) => n,
                Ok(None) => continue,
                Err(e) => {
                    log::warn!("the Ouster's IMU port: cannot receive: {e}; no more IMU readings");
                    break;
                }
            };
            let packet = ImuPacket::read(&buf[..n], &self.imu_to_sensor);
            let mut dropped = 0;
            if let Ok(reading) = packet {
                if let Ok(mut r) = self.readings.lock() {
                    if r.len() == KEPT {
                        r.pop_front();
                        dropped = 1;
                    }
                    r.push_back(reading);
                }
            }
            if let Ok(mut s) = self.stats.lock() {
                if let Some(c) = &mut s.imu_port {
                    c.packets += u64::from(packet.is_ok());
                    c.bad_packets += u64::from(packet.is_err());
                    c.dropped += dropped;
                }
            }
        }
    }
}
