//! The ROS 1 bag, MCAP and ROS 2 `.db3` readers on arbitrary files (the first byte picks the
//! container's magic, the rest follows it): listing the topics and reading every message of
//! each returns messages or errors, never panics. (SQLite itself is fuzzed upstream; this
//! exercises our queries and what we do with what they return.)
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::recording::{mcap, ros2, rosbag1, Container};

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let magic = match pick % 3 {
        0 => rosbag1::MAGIC,
        1 => mcap::MAGIC,
        _ => ros2::SQLITE_MAGIC,
    };
    let path = std::env::temp_dir().join(format!("slamesh-fuzz-recording-{}", std::process::id()));
    std::fs::write(&path, [magic, rest].concat()).unwrap();
    if let Some(Ok(container)) = Container::detect(&path) {
        if let Ok(topics) = container.topics() {
            for t in topics.iter().take(4) {
                if let Ok(messages) = container.messages(&t.name) {
                    messages.take(64).for_each(drop);
                }
            }
        }
    }
    let _ = std::fs::remove_file(&path);
});
