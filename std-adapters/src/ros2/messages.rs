//! The messages the node sends and takes ([`crate::formats::ros_messages`]), as ros2-client
//! takes them.

pub use crate::formats::ros_messages::*;

macro_rules! message {
    ($($t:ty),* $(,)?) => {
        $(impl ros2_client::Message for $t {})*
    };
}

message!(
    Odometry,
    TfMessage,
    PathMsg,
    PoseWithCovarianceStamped,
    DiagnosticArray,
    MarkerArray,
    OccupancyGrid,
    Imu,
    Clock,
    TriggerRequest,
    TriggerResponse,
);
