//! The ROS 2 node's command line and parameter files on arbitrary text: a parameter file's
//! reader and the `--ros-args` reader return their values or an error, never panic, and the
//! arguments they accept keep every rename they name.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::ros_args::{parse_params_file, RosArgs};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_params_file(text, "/ns/slamesh");
    let args: Vec<String> = text.split_whitespace().map(String::from).collect();
    if let Ok(a) = RosArgs::parse(&args) {
        for (from, to) in &a.remaps {
            assert!(!from.is_empty() && !to.is_empty());
        }
    }
});
