//! The TOML readers on arbitrary text: every configuration the configuration reader accepts is
//! one the pipeline accepts too, and every robot file the navigation map's reader accepts
//! passes its own check.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh_core::{Pipeline, SmallCapacity};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(settings) = slamesh::run::config_file::parse(text) {
        assert!(settings.config.validate().is_ok());
        assert!(Pipeline::<SmallCapacity>::new(settings.config).is_ok());
    }
    if let Ok(robot) = slamesh::navmap::Robot::parse(text) {
        assert!(robot.check().is_ok());
    }
});
