//! Services (and the action's services) on DDS, in the request/reply mapping of each peer.
//!
//! ROS 2's RMWs put a request's identity in different places: `rmw_cyclonedds_cpp` in a
//! 16-byte header before the request (the Cyclone mapping), `rmw_fastrtps_cpp` and
//! `rmw_connextdds` in the sample's related-sample-identity (the Enhanced mapping of the
//! RPC over DDS spec, 7.2.4). A node fixed to one mapping serves only peers of that RMW. With
//! `service_mapping: auto` (the default) each service is served both ways: one server per
//! mapping on the same topics, and each request is answered by the server of its peer's
//! mapping, the other one ignoring it. The peer's mapping is read from the vendor id that
//! opens the GUID prefix of the request's writer (DDSI-RTPS 2.5, 9.3.1.5: "the first two
//! bytes of the guidPrefix" are the vendor id): Eclipse Cyclone DDS (0x0110) uses the Cyclone
//! mapping, every other vendor (eProsima Fast DDS 0x010f, RTI Connext 0x0101, RustDDS 0x0112)
//! the Enhanced one. `service_mapping: cyclone` or `enhanced` serves one mapping to every peer.

use futures::future::{select_all, BoxFuture};
use ros2_client::{Message, Name, Node, RmwRequestId, Server, ServiceMapping, ServiceTypeName};
use serde::{de::DeserializeOwned, Serialize};

use crate::params::{Mapping, Params};
use crate::qos;

/// The RTPS vendor id of Eclipse Cyclone DDS (the OMG's list of vendor ids).
pub const VENDOR_CYCLONE: [u8; 2] = [0x01, 0x10];

/// The mapping of the peer whose request carries `id`: Cyclone for a Cyclone DDS writer,
/// Enhanced for any other vendor's.
pub fn peer_mapping(id: &RmwRequestId) -> ServiceMapping {
    if id.writer_gid.to_bytes16()[..2] == VENDOR_CYCLONE {
        ServiceMapping::Cyclone
    } else {
        ServiceMapping::Enhanced
    }
}

/// The mappings the node serves: the one `service_mapping` names, else both (the first one is
/// where the action publishes its feedback and statuses: those topics carry no request id).
pub fn mappings(params: &Params) -> Vec<ServiceMapping> {
    match params.service_mapping {
        Some(m) => vec![m.to_ros2()],
        None => vec![Mapping::Enhanced.to_ros2(), Mapping::Cyclone.to_ros2()],
    }
}

/// Whether the server of `mapping`, one of `served`, answers the request `id`: always when it
/// is the only one, else when `mapping` is the peer's.
pub fn answers(mapping: ServiceMapping, served: usize, id: &RmwRequestId) -> bool {
    served == 1 || peer_mapping(id) == mapping
}

/// A request: which server received it (to answer through it), its id, the request.
pub struct Request<Q> {
    /// The index of the server that answers it.
    pub server: usize,
    /// The request's id.
    pub id: RmwRequestId,
    /// The request.
    pub request: Q,
}

/// One service, served in the mappings of [`mappings`].
pub struct Service<Q: Message, P: Message> {
    servers: Vec<(ServiceMapping, Server<Q, P>)>,
    name: String,
}

/// How many failed reads in a row before a pause: a reader that keeps failing without
/// consuming anything must not spin the runtime.
const FAILURES_BEFORE_PAUSE: u32 = 8;
/// The pause.
const ERROR_BACKOFF: std::time::Duration = std::time::Duration::from_millis(100);

impl<Q, P> Service<Q, P>
where
    Q: Message + Clone + Serialize + DeserializeOwned + Send + Sync + 'static,
    P: Message + Clone + Serialize + DeserializeOwned + Send + Sync + 'static,
{
    /// Creates the service `name` of type `type_name` on `node` (rmw's default service QoS).
    pub fn create(
        node: &mut Node,
        params: &Params,
        name: &Name,
        type_name: &ServiceTypeName,
    ) -> Result<Self, String> {
        let servers = mappings(params)
            .into_iter()
            .map(|m| {
                node.create_server::<Q, P>(m, name, type_name, qos::services(), qos::services())
                    .map(|s| (m, s))
                    .map_err(|e| format!("service {name}: {e:?}"))
            })
            .collect::<Result<_, _>>()?;
        Ok(Service {
            servers,
            name: name.to_string(),
        })
    }

    /// The next request this node answers (requests for the other mapping's server, and
    /// requests that do not decode, are skipped).
    pub async fn receive(&self) -> Request<Q> {
        let mut failures = 0;
        loop {
            let reads = self.servers.iter().enumerate().map(|(i, (_, s))| {
                Box::pin(async move { (i, s.async_receive_request().await) }) as BoxFuture<'_, _>
            });
            let ((server, read), _, _): (
                (usize, ros2_client::ReadResult<(RmwRequestId, Q)>),
                _,
                _,
            ) = select_all(reads).await;
            match read {
                Ok((id, request)) => {
                    failures = 0;
                    if answers(self.servers[server].0, self.servers.len(), &id) {
                        return Request {
                            server,
                            id,
                            request,
                        };
                    }
                }
                Err(e) => {
                    // With two mappings served, each request fails to decode in one of them.
                    tracing::debug!("{}: a request not read: {e:?}", self.name);
                    failures += 1;
                    if failures >= FAILURES_BEFORE_PAUSE {
                        failures = 0;
                        tokio::time::sleep(ERROR_BACKOFF).await;
                    }
                }
            }
        }
    }

    /// Answers `request` through the server that received it.
    pub fn respond(&self, server: usize, id: RmwRequestId, response: P) -> Result<(), String> {
        self.servers[server]
            .1
            .send_response(id, response)
            .map_err(|e| format!("{}: answering failed: {e:?}", self.name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(prefix: [u8; 2]) -> RmwRequestId {
        let mut gid = [7u8; 16];
        gid[..2].copy_from_slice(&prefix);
        RmwRequestId {
            writer_gid: ros2_client::Gid::from(gid),
            sequence_number: 1,
        }
    }

    #[test]
    fn each_request_is_answered_in_its_peers_mapping() {
        let (cyclone, fast_dds, rustdds) = (id([0x01, 0x10]), id([0x01, 0x0f]), id([0x01, 0x12]));
        assert_eq!(peer_mapping(&cyclone), ServiceMapping::Cyclone);
        assert_eq!(peer_mapping(&fast_dds), ServiceMapping::Enhanced);
        assert_eq!(peer_mapping(&rustdds), ServiceMapping::Enhanced);
        assert!(answers(ServiceMapping::Cyclone, 2, &cyclone));
        assert!(!answers(ServiceMapping::Enhanced, 2, &cyclone));
        assert!(!answers(ServiceMapping::Cyclone, 2, &fast_dds));
        // One mapping served (service_mapping set): it answers every peer.
        assert!(answers(ServiceMapping::Cyclone, 1, &fast_dds));
        let mut p = Params::default();
        assert_eq!(mappings(&p).len(), 2);
        p.service_mapping = Some(Mapping::Cyclone);
        assert_eq!(mappings(&p), vec![ServiceMapping::Cyclone]);
    }
}
