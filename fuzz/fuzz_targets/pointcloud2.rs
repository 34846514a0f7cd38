//! The PointCloud2 decoder on arbitrary bytes, in both serialisations and as the CDR body a
//! ROS 2 node's DDS reader hands over: it returns a cloud or an error, never panics, and keeps
//! no more points than the message describes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::pointcloud2::Cloud;

fuzz_target!(|data: &[u8]| {
    let body = data.get(1..).unwrap_or_default();
    let big = data.first().is_some_and(|b| b & 1 == 0);
    for cloud in [
        Cloud::parse_ros1(data),
        Cloud::parse_cdr(data),
        Cloud::parse_cdr_body(body, big),
    ] {
        let Ok(c) = cloud else { continue };
        if let Ok(d) = c.decode() {
            assert!(d.points.len() <= c.width as usize * c.height as usize);
            assert!(d.points.iter().flatten().all(|v| v.is_finite()));
            if let Some(t) = &d.times {
                assert_eq!(t.len(), d.points.len());
            }
        }
    }
});
