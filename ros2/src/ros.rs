//! The DDS side: the context (domain, interfaces), the node, its names, and its spinner.

use std::net::IpAddr;

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::{Context, Name, Node, NodeName, NodeOptions};

use crate::params::Params;

/// The context of `params.domain_id`, on the interfaces of `params.dds_interfaces` (all when
/// empty). `Context::new()` of ros2-client 0.12.1 always joins domain 0 and ignores
/// `ROS_DOMAIN_ID`, so the participant is built here.
pub fn context(params: &Params) -> Result<Context, String> {
    let mut builder = DomainParticipantBuilder::new(params.domain_id);
    if !params.dds_interfaces.is_empty() {
        let addrs: Vec<IpAddr> = params.dds_interfaces.clone();
        builder = builder.with_only_networks(addrs);
    }
    let participant = builder
        .build()
        .map_err(|e| format!("DDS participant on domain {}: {e:?}", params.domain_id))?;
    Context::from_domain_participant(participant).map_err(|e| format!("ROS context: {e:?}"))
}

/// The node, with its spinner (discovery, the graph, parameter services) running on the
/// current tokio runtime.
/// `rosout`: whether the node publishes its log on `/rosout`. ros2-client's parameter
/// services are off: the node serves its own ([`crate::param_services`]), with descriptors,
/// ranges and the request/reply mapping of each peer.
pub fn node(context: &Context, params: &Params, rosout: bool) -> Result<Node, String> {
    let name = NodeName::new(&params.namespace, &params.node_name)
        .map_err(|e| format!("node name: {e}"))?;
    let options = NodeOptions::new()
        .enable_rosout(rosout)
        .start_parameter_services(false);
    let mut node = context
        .new_node(name, options)
        .map_err(|e| format!("node: {e:?}"))?;
    let spinner = node.spinner().map_err(|e| format!("spinner: {e:?}"))?;
    tokio::spawn(async move {
        if let Err(e) = spinner.spin().await {
            tracing::error!("the ROS spinner stopped: {e:?}");
        }
    });
    Ok(node)
}

/// `~/base`: a name under the node's own name (`/gripper/home`), after the remapping rules.
/// Built absolute: ros2-client 0.12.1 expands neither `~` nor, correctly, a relative name in
/// the root namespace (it would give `rq//home...`).
pub fn private_name(params: &Params, base: &str) -> Result<Name, String> {
    resolved(params, &format!("~/{base}"))
}

/// `base` in the node's namespace (`/joint_states`, `/left/joint_states`), after the
/// remapping rules (`-r joint_states:=/joint_states`).
pub fn namespaced_name(params: &Params, base: &str) -> Result<Name, String> {
    resolved(params, base)
}

/// `/base`: a global name (`/diagnostics`, which the diagnostic aggregator reads), after the
/// remapping rules.
pub fn global_name(params: &Params, base: &str) -> Result<Name, String> {
    resolved(params, &format!("/{base}"))
}

/// `name` expanded and remapped as rcl resolves a topic or service name, as a ros2-client
/// name (its namespace, its last token).
fn resolved(params: &Params, name: &str) -> Result<Name, String> {
    let full = params.expand(name).map_err(|e| e.0)?;
    let full = params.remap(&full);
    let (ns, base) = full
        .rsplit_once('/')
        .ok_or_else(|| format!("name {full}: not absolute"))?;
    let ns = if ns.is_empty() { "/" } else { ns };
    Name::new(ns, base).map_err(|e| format!("name {full}: {e}"))
}
