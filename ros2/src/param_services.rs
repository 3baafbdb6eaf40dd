//! The node's parameters, declared and served through rcl's six parameter services
//! (`~/list_parameters`, `~/get_parameters`, `~/get_parameter_types`, `~/set_parameters`,
//! `~/set_parameters_atomically`, `~/describe_parameters`, `rcl_interfaces` types), so that
//! `ros2 param list/get/set/describe/dump` work, in each peer's request/reply mapping
//! ([`crate::rpc`]).
//!
//! Each parameter has its type, a description, and its range where it has one. Most take
//! effect at start only and are **read-only** here (a set is refused, as rclcpp refuses one of
//! a read-only parameter); `allow_stalling` takes effect for the next goal that ends, and
//! `use_sim_time` is accepted (the node stamps with the system clock all the same).
//!
//! Each change is published on `/parameter_events` (`rcl_interfaces/msg/ParameterEvent`, as
//! rclcpp publishes it: the declarations once at start, then each set), which rqt and
//! `ros2 param` tools watch.
//!
//! ros2-client 0.12.1's own parameter services are not used: they always use the Enhanced
//! mapping, and their descriptors carry neither description nor range.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

use ros2_client::parameters::{raw, ParameterValue};
use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParameterTypesRequest,
    GetParameterTypesResponse, GetParametersRequest, GetParametersResponse, ListParametersRequest,
    ListParametersResponse, ListParametersResult, SetParametersAtomicallyResponse,
    SetParametersRequest, SetParametersResponse,
};
use ros2_client::{Context, Message, Node, Publisher, ServiceTypeName};
use serde::{de::DeserializeOwned, Serialize};
use tokio::sync::watch;

use crate::params::{Live, Params, PositionConvention};
use crate::{ros, rpc};

/// One declared parameter.
#[derive(Clone, Debug)]
pub struct Declared {
    /// Its descriptor (name, type, description, constraints, range, read-only).
    pub descriptor: raw::ParameterDescriptor,
    /// Its value.
    pub value: ParameterValue,
}

/// A numeric range: integers `from..=to`, or floats.
enum Range {
    None,
    Integer(i64, i64),
    Float(f64, f64),
}

fn declared(
    name: &str,
    value: ParameterValue,
    description: &str,
    constraints: &str,
    range: Range,
    read_only: bool,
) -> Declared {
    let (integer_range, floating_point_range) = match range {
        Range::None => (Vec::new(), Vec::new()),
        Range::Integer(from_value, to_value) => (
            vec![raw::IntegerRange {
                from_value,
                to_value,
                step: 0,
            }],
            Vec::new(),
        ),
        Range::Float(from_value, to_value) => (
            Vec::new(),
            vec![raw::FloatingPointRange {
                from_value,
                to_value,
                step: 0.0,
            }],
        ),
    };
    Declared {
        descriptor: raw::ParameterDescriptor {
            name: name.to_owned(),
            r#type: ParameterValue::to_parameter_type_raw(&value),
            description: description.to_owned(),
            additional_constraints: constraints.to_owned(),
            read_only,
            dynamic_typing: false,
            floating_point_range,
            integer_range,
        },
        value,
    }
}

/// Every parameter of the node with its value in `p` (the README's table, with types and
/// ranges).
pub fn declarations(p: &Params) -> Vec<Declared> {
    use ParameterValue::{Boolean, Double, DoubleArray, Integer, String as Text, StringArray};
    let text = |s: &str| Text(s.to_owned());
    let ro = true;
    let at_start = "read-only: set it at start (parameter file, -p)";
    vec![
        declared(
            "device",
            text(match p.device {
                crate::params::DeviceKind::Wsg => "wsg",
                crate::params::DeviceKind::Griplink => "griplink",
                crate::params::DeviceKind::SmartGrasp => "smartgrasp",
            }),
            "the device: a Weiss WSG, a GRIPLINK port or the SCHUNK 2D Grasping-Kit",
            &format!("wsg, griplink or smartgrasp; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "transport",
            text(&p.transport),
            "WSG: the transport",
            &format!("tcp, udp or serial; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "address",
            text(&p.address),
            "host:port of the device",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "serial_port",
            text(&p.serial_port),
            "WSG over RS-232: the serial device",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "baud_rate",
            Integer(p.baud_rate.into()),
            "WSG over RS-232: the baud rate",
            at_start,
            Range::Integer(1, u32::MAX.into()),
            ro,
        ),
        declared(
            "griplink_port",
            Integer(p.griplink_port.into()),
            "the GRIPLINK port this node drives",
            at_start,
            Range::Integer(0, 3),
            ro,
        ),
        declared(
            "joint_names",
            StringArray(p.joint_names.clone()),
            "the joints joint_states names",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "joint_multipliers",
            DoubleArray(p.joint_multipliers.clone()),
            "joint position per metre of opening, one per joint name (empty: from the number \
             of names)",
            &format!("empty or one per joint name; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "joint_offsets",
            DoubleArray(p.joint_offsets.clone()),
            "joint position at a closed gripper, one per joint name (empty: all 0)",
            &format!("empty or one per joint name; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "position_convention",
            text(match p.position_convention {
                PositionConvention::Width => "width",
                PositionConvention::Finger => "finger",
            }),
            "positions are the opening between the fingers (width) or each finger's distance \
             from the centre (finger), m",
            &format!("width or finger; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "joint_states_rate_hz",
            Double(p.joint_states_rate_hz),
            "the rate of joint_states, Hz",
            at_start,
            Range::Float(0.1, 1000.0),
            ro,
        ),
        declared(
            "speed_m_per_s",
            Double(p.speed_m_per_s),
            "finger speed of goals, m/s (clamped to the device's limits)",
            &format!("> 0; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "goal_tolerance_m",
            Double(p.goal_tolerance_m),
            "a goal's position is reached within this, m",
            &format!("> 0; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "default_effort_n",
            Double(p.default_effort_n),
            "GRIPLINK: the grip force of a goal whose max_effort is 0, N (0: such a grip is \
             rejected)",
            &format!(">= 0; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "grasp_on_close",
            Boolean(p.grasp_on_close),
            "WSG: a closing goal that stops on a part grasps it there (0x25)",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "allow_stalling",
            Boolean(p.allow_stalling),
            "a goal whose fingers stall before its position (a part held) is SUCCEEDED, not \
             ABORTED (gripper_action_controller's parameter)",
            "takes effect for the next goal that ends",
            Range::None,
            false,
        ),
        declared(
            "auto_acknowledge_fast_stop",
            Boolean(p.auto_acknowledge_fast_stop),
            "acknowledge a FAST STOP found after a reconnect",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "reconnect",
            Boolean(p.reconnect),
            "reconnect a lost link",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "service_mapping",
            text(match p.service_mapping {
                None => "auto",
                Some(crate::params::Mapping::Cyclone) => "cyclone",
                Some(crate::params::Mapping::Enhanced) => "enhanced",
            }),
            "the request/reply mapping of services and the action (auto: each peer's)",
            &format!("auto, cyclone or enhanced; {at_start}"),
            Range::None,
            ro,
        ),
        declared(
            "frame_id",
            text(&p.frame_id),
            "Grasping-Kit: the frame of ~/grasp_pose",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "object_class",
            Integer(p.object_class.into()),
            "Grasping-Kit: the object class to ask grasps for (0: any)",
            at_start,
            Range::Integer(0, 65_535),
            ro,
        ),
        declared(
            "dds_interfaces",
            StringArray(p.dds_interfaces.iter().map(|a| a.to_string()).collect()),
            "the IP addresses of the interfaces DDS uses (empty: all)",
            at_start,
            Range::None,
            ro,
        ),
        declared(
            "use_sim_time",
            Boolean(p.use_sim_time),
            "accepted for launch files; the node stamps with the system clock (it drives a \
             device in real time)",
            "",
            Range::None,
            false,
        ),
    ]
}

/// Where a store publishes its changes: `/parameter_events` and the node's full name.
pub struct Events {
    /// The publisher on `/parameter_events`.
    pub publisher: Publisher<raw::ParameterEvent>,
    /// The node's fully qualified name, the events' `node`.
    pub node: String,
}

/// The declared parameters and what a set changes.
pub struct Store {
    params: Mutex<Vec<Declared>>,
    live: Live,
    events: Option<Events>,
}

impl Store {
    /// The parameters of `params`; a set of `allow_stalling` reaches `live`; changes are
    /// published through `events`, the declarations at once.
    pub fn new(params: &Params, live: Live, events: Option<Events>) -> Self {
        let store = Store {
            params: Mutex::new(declarations(params)),
            live,
            events,
        };
        let declared: Vec<raw::Parameter> = store
            .lock()
            .iter()
            .map(|d| raw::Parameter {
                name: d.descriptor.name.clone(),
                value: d.value.clone().into(),
            })
            .collect();
        store.publish(declared, Vec::new());
        store
    }

    fn publish(
        &self,
        new_parameters: Vec<raw::Parameter>,
        changed_parameters: Vec<raw::Parameter>,
    ) {
        let Some(events) = &self.events else {
            return;
        };
        let event = raw::ParameterEvent {
            stamp: ros2_client::builtin_interfaces::Time::now(),
            node: events.node.clone(),
            new_parameters,
            changed_parameters,
            deleted_parameters: Vec::new(),
        };
        if let Err(e) = events.publisher.publish(event) {
            tracing::debug!("parameter event not sent: {e:?}");
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Declared>> {
        self.params.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `ListParameters`: the names under the prefixes (all without prefixes), to `depth`
    /// dot-separated levels (0: any), as rclcpp lists them.
    pub fn list(&self, req: &ListParametersRequest) -> ListParametersResult {
        let names = self
            .lock()
            .iter()
            .map(|d| d.descriptor.name.clone())
            .filter(|n| {
                let deep_enough = req.depth == 0 || (n.matches('.').count() as u64) < req.depth;
                let under = req.prefixes.is_empty()
                    || req
                        .prefixes
                        .iter()
                        .any(|p| n == p || n.starts_with(&format!("{p}.")));
                deep_enough && under
            })
            .collect();
        ListParametersResult {
            names,
            // No name of ours has a dot: there are no prefixes to report.
            prefixes: Vec::new(),
        }
    }

    /// `GetParameters`: the values (NOT_SET for a name not declared).
    pub fn get(&self, names: &[String]) -> Vec<raw::ParameterValue> {
        let params = self.lock();
        names
            .iter()
            .map(|n| {
                params
                    .iter()
                    .find(|d| d.descriptor.name == *n)
                    .map_or(ParameterValue::NotSet, |d| d.value.clone())
                    .into()
            })
            .collect()
    }

    /// `GetParameterTypes`: the types (NOT_SET for a name not declared).
    pub fn types(&self, names: &[String]) -> Vec<u8> {
        let params = self.lock();
        names
            .iter()
            .map(|n| {
                params
                    .iter()
                    .find(|d| d.descriptor.name == *n)
                    .map_or(raw::ParameterType::NOT_SET, |d| d.descriptor.r#type)
            })
            .collect()
    }

    /// `DescribeParameters`: the descriptors; none at all if a name is not declared (rclcpp's
    /// service catches ParameterNotDeclaredException and answers an empty list).
    pub fn describe(&self, names: &[String]) -> Vec<raw::ParameterDescriptor> {
        let params = self.lock();
        names
            .iter()
            .map(|n| {
                params
                    .iter()
                    .find(|d| d.descriptor.name == *n)
                    .map(|d| d.descriptor.clone())
            })
            .collect::<Option<Vec<_>>>()
            .unwrap_or_default()
    }

    /// Why `value` cannot be set on `name`, with rclcpp's reasons; `None`: it can.
    fn refusal(params: &[Declared], name: &str, value: &ParameterValue) -> Option<String> {
        let Some(d) = params.iter().find(|d| d.descriptor.name == name) else {
            return Some(format!("parameter '{name}' is not declared"));
        };
        if d.descriptor.read_only {
            return Some(format!(
                "parameter {{{name}}} cannot be set because it is read-only"
            ));
        }
        let to = ParameterValue::to_parameter_type_raw(value);
        if to != d.descriptor.r#type {
            return Some(format!(
                "Wrong parameter type, parameter {{{name}}} is of type {{{}}}, setting it to \
                 {{{}}} is not allowed.",
                type_name(d.descriptor.r#type),
                type_name(to)
            ));
        }
        None
    }

    fn apply(&self, params: &mut [Declared], name: &str, value: ParameterValue) {
        match (name, &value) {
            ("allow_stalling", ParameterValue::Boolean(b)) => {
                self.live.allow_stalling.store(*b, Ordering::Relaxed)
            }
            ("use_sim_time", ParameterValue::Boolean(true)) => tracing::warn!(
                "use_sim_time: true is accepted, but the node stamps with the system clock"
            ),
            _ => {}
        }
        tracing::info!("parameter {name} set to {value:?}");
        if let Some(d) = params.iter_mut().find(|d| d.descriptor.name == name) {
            d.value = value.clone();
        }
        let changed = raw::Parameter {
            name: name.to_owned(),
            value: value.into(),
        };
        self.publish(Vec::new(), vec![changed]);
    }

    /// `SetParameters`: each parameter set on its own, one result each.
    pub fn set(&self, parameters: Vec<raw::Parameter>) -> Vec<raw::SetParametersResult> {
        let mut params = self.lock();
        parameters
            .into_iter()
            .map(|p| {
                let value = ParameterValue::from(p.value);
                match Store::refusal(&params, &p.name, &value) {
                    Some(reason) => raw::SetParametersResult {
                        successful: false,
                        reason,
                    },
                    None => {
                        self.apply(&mut params, &p.name, value);
                        raw::SetParametersResult {
                            successful: true,
                            reason: String::new(),
                        }
                    }
                }
            })
            .collect()
    }

    /// `SetParametersAtomically`: all or none.
    pub fn set_atomically(&self, parameters: Vec<raw::Parameter>) -> raw::SetParametersResult {
        let mut params = self.lock();
        let parameters: Vec<(String, ParameterValue)> = parameters
            .into_iter()
            .map(|p| (p.name, ParameterValue::from(p.value)))
            .collect();
        if let Some(reason) = parameters
            .iter()
            .find_map(|(n, v)| Store::refusal(&params, n, v))
        {
            return raw::SetParametersResult {
                successful: false,
                reason,
            };
        }
        for (n, v) in parameters {
            self.apply(&mut params, &n, v);
        }
        raw::SetParametersResult {
            successful: true,
            reason: String::new(),
        }
    }
}

/// rclcpp's name of a parameter type, for its reasons.
fn type_name(t: u8) -> &'static str {
    match t {
        raw::ParameterType::BOOL => "bool",
        raw::ParameterType::INTEGER => "integer",
        raw::ParameterType::DOUBLE => "double",
        raw::ParameterType::STRING => "string",
        raw::ParameterType::BYTE_ARRAY => "byte_array",
        raw::ParameterType::BOOL_ARRAY => "bool_array",
        raw::ParameterType::INTEGER_ARRAY => "integer_array",
        raw::ParameterType::DOUBLE_ARRAY => "double_array",
        raw::ParameterType::STRING_ARRAY => "string_array",
        _ => "not set",
    }
}

/// What the parameter services are created with.
struct Spawner<'a> {
    node: &'a mut Node,
    params: &'a Params,
    store: Arc<Store>,
    shutdown: &'a watch::Receiver<bool>,
}

impl Spawner<'_> {
    /// Serves the parameter service `~/name` (type `rcl_interfaces/srv/<Name>`, in camel
    /// case) with `answer` until shutdown.
    fn serve<Q, P>(&mut self, name: &str, answer: fn(&Store, Q) -> P) -> Result<(), String>
    where
        Q: Message + Clone + Serialize + DeserializeOwned + Send + Sync + 'static,
        P: Message + Clone + Serialize + DeserializeOwned + Send + Sync + 'static,
    {
        let type_name = name
            .split('_')
            .map(|w| {
                let mut c = w.chars();
                c.next()
                    .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                    .unwrap_or_default()
            })
            .collect::<String>();
        let service = rpc::Service::<Q, P>::create(
            self.node,
            self.params,
            &ros::private_name(self.params, name)?,
            &ServiceTypeName::new("rcl_interfaces", &type_name),
        )?;
        let (store, mut shutdown) = (self.store.clone(), self.shutdown.clone());
        tokio::spawn(async move {
            loop {
                let r = tokio::select! {
                    r = service.receive() => r,
                    _ = shutdown.wait_for(|s| *s) => return,
                };
                let response = answer(&store, r.request);
                if let Err(e) = service.respond(r.server, r.id, response) {
                    tracing::warn!("{e}");
                }
            }
        });
        Ok(())
    }
}

/// Declares the node's parameters and serves the six parameter services until `shutdown`.
pub fn spawn(
    context: &Context,
    node: &mut Node,
    params: &Params,
    live: &Live,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let publisher = node
        .create_publisher(&context.get_parameter_events_topic(), None)
        .map_err(|e| format!("/parameter_events: {e:?}"))?;
    let events = Events {
        publisher,
        node: params.fully_qualified_name(),
    };
    let store = Arc::new(Store::new(params, live.clone(), Some(events)));
    let mut s = Spawner {
        node,
        params,
        store,
        shutdown,
    };
    s.serve("list_parameters", |s, q: ListParametersRequest| {
        ListParametersResponse { result: s.list(&q) }
    })?;
    s.serve("get_parameters", |s, q: GetParametersRequest| {
        GetParametersResponse {
            values: s.get(&q.names),
        }
    })?;
    s.serve("get_parameter_types", |s, q: GetParameterTypesRequest| {
        GetParameterTypesResponse {
            values: s.types(&q.names),
        }
    })?;
    s.serve("set_parameters", |s, q: SetParametersRequest| {
        SetParametersResponse {
            results: s.set(q.parameter),
        }
    })?;
    s.serve("set_parameters_atomically", |s, q: SetParametersRequest| {
        SetParametersAtomicallyResponse {
            result: s.set_atomically(q.parameter),
        }
    })?;
    s.serve("describe_parameters", |s, q: DescribeParametersRequest| {
        DescribeParametersResponse {
            values: s.describe(&q.names),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn param(name: &str, value: ParameterValue) -> raw::Parameter {
        raw::Parameter {
            name: name.to_owned(),
            value: value.into(),
        }
    }

    #[test]
    fn every_parameter_is_declared_once() {
        let names: Vec<String> = declarations(&Params::default())
            .into_iter()
            .map(|d| d.descriptor.name)
            .collect();
        let mut sorted = names.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), names.len(), "a name declared twice");
        let mut known: Vec<&str> = crate::params::NAMES.to_vec();
        known.sort();
        assert_eq!(sorted, known);
    }

    #[test]
    fn get_set_describe_as_rclcpp_answers() {
        let live = Live::default();
        let s = Store::new(&Params::default(), live.clone(), None);
        let all = s.list(&ListParametersRequest {
            prefixes: Vec::new(),
            depth: 0,
        });
        assert_eq!(all.names.len(), crate::params::NAMES.len());
        let some = s.list(&ListParametersRequest {
            prefixes: vec!["allow_stalling".into()],
            depth: 1,
        });
        assert_eq!(some.names, vec!["allow_stalling".to_owned()]);

        let values = s.get(&["joint_states_rate_hz".into(), "nope".into()]);
        assert_eq!(
            ParameterValue::from(values[0].clone()),
            ParameterValue::Double(50.0)
        );
        assert_eq!(values[1].ptype, raw::ParameterType::NOT_SET);
        assert_eq!(
            s.types(&["griplink_port".into(), "nope".into()]),
            vec![raw::ParameterType::INTEGER, raw::ParameterType::NOT_SET]
        );

        let d = &s.describe(&["griplink_port".into()])[0];
        assert!(d.read_only && !d.description.is_empty());
        assert_eq!(
            (d.integer_range[0].from_value, d.integer_range[0].to_value),
            (0, 3)
        );
        assert!(s
            .describe(&["griplink_port".into(), "nope".into()])
            .is_empty());

        // allow_stalling is live; a read-only one, a wrong type, an unknown name are refused.
        let results = s.set(vec![
            param("allow_stalling", ParameterValue::Boolean(true)),
            param("speed_m_per_s", ParameterValue::Double(0.1)),
            param("allow_stalling", ParameterValue::Integer(1)),
            param("nope", ParameterValue::Boolean(true)),
        ]);
        let ok: Vec<bool> = results.iter().map(|r| r.successful).collect();
        assert_eq!(ok, vec![true, false, false, false]);
        assert!(results[1].reason.contains("read-only"), "{results:?}");
        assert!(
            results[2].reason.contains("Wrong parameter type"),
            "{results:?}"
        );
        assert!(live.allow_stalling.load(Ordering::Relaxed));
        assert_eq!(
            ParameterValue::from(s.get(&["allow_stalling".into()])[0].clone()),
            ParameterValue::Boolean(true)
        );

        // All or nothing.
        let r = s.set_atomically(vec![
            param("allow_stalling", ParameterValue::Boolean(false)),
            param("reconnect", ParameterValue::Boolean(false)),
        ]);
        assert!(!r.successful);
        assert!(
            live.allow_stalling.load(Ordering::Relaxed),
            "changed by a refused set"
        );
        let r = s.set_atomically(vec![
            param("allow_stalling", ParameterValue::Boolean(false)),
            param("use_sim_time", ParameterValue::Boolean(true)),
        ]);
        assert!(r.successful);
        assert!(!live.allow_stalling.load(Ordering::Relaxed));
    }
}
