//! The QoS profiles of the node's topics and services: the ROS 2 defaults.

use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::QosProfile;

/// rclcpp's default for topics (`rclcpp::QoS(10)`): reliable, volatile, keep last 10.
///
/// A full send window fails the publish at once instead of blocking the node's runtime (the
/// next sample follows within one period anyway).
///
/// Also for `joint_states`: `robot_state_publisher` and `joint_state_broadcaster` use this
/// profile, and a reliable writer serves best-effort readers too, whereas a best-effort
/// ("sensor data") writer would not be matched by the default reliable reader.
pub fn topic() -> QosProfile {
    QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Fail,
        })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// rmw's default for services: reliable, volatile, keep last 10. A reply waits up to
/// ros2-client's default 100 ms for room rather than being lost.
pub fn services() -> QosProfile {
    topic().reliability(Reliability::Reliable {
        when_full: WhenFull::DEFAULT,
    })
}

/// rcl_action's goal status topic: reliable, transient local, keep last 1.
pub fn status() -> QosProfile {
    topic()
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}
