//! Pure pairing of responses to requests, with every check the protocol offers. No I/O: the task
//! feeds it, so each rule is tested on its own.
//!
//! Responses carry no request id; they come back in the order the requests were sent (one TCP
//! stream, one server loop), so pairing is in order. What the header offers is checked:
//! - communication type must be "response" and the prefix version 3;
//! - the message type must be the request's (manual 3.3; errata: GET_OBJECT_COUNT answers 32);
//! - the response counter must advance by one modulo 256 (manual 3.2.2.3). The first response's
//!   counter is unknown to a fresh connection and is learned. A gap of `k` means the `k`
//!   responses before this one were lost; with in-order delivery those belong to the `k` oldest
//!   waiting requests, which get [`Error::ResponseLost`] instead of someone else's answer. A gap
//!   that no waiting request can explain breaks the connection.
//! - the fields a SUCCESS response repeats from its request must match ([`check_response`]).
//!
//! What no check can see (V3 frames carry no checksum): a corrupted body byte that still makes a
//! valid value (a count, a pose, a server state, a response code) reaches the caller as it is.

use crate::smartgrasp::error::{Error, Malformed};
use crate::smartgrasp::frame::{RequestFrame, ResponseFrame, PROTOCOL_VERSION};
use crate::smartgrasp::types::{CommunicationType, MessageType, ResponseCode};

/// The response counter's expectations across a connection.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Pairing {
    /// The counter the next response must carry; `None` until the first response.
    next_counter: Option<u8>,
}

/// Lost responses found by [`Pairing::counter`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Lost {
    /// How many of the oldest waiting requests lost their response.
    pub count: usize,
    /// The counter the first lost response would have carried.
    pub first_expected: u8,
}

impl Pairing {
    /// Checks the counter of a response that arrived while `waiting` requests (the abandoned ones
    /// included) were outstanding. `Ok(lost)`: fail `lost.count` oldest requests with
    /// [`Error::ResponseLost`], then pair the response with the next. `Err`: the connection must
    /// be closed.
    pub(crate) fn counter(&mut self, received: u8, waiting: usize) -> Result<Lost, Error> {
        if waiting == 0 {
            return Err(Malformed::Unsolicited { counter: received }.into());
        }
        let expected = self.next_counter.unwrap_or(received);
        let count = usize::from(received.wrapping_sub(expected));
        if count >= waiting {
            return Err(Error::ResponseLost { expected, received });
        }
        self.next_counter = Some(received.wrapping_add(1));
        Ok(Lost {
            count,
            first_expected: expected,
        })
    }
}

/// Checks a response's prefix and header against the request it is paired with.
pub(crate) fn check_header(request: MessageType, frame: &ResponseFrame) -> Result<(), Malformed> {
    if frame.version != PROTOCOL_VERSION {
        return Err(Malformed::Version {
            version: frame.version,
        });
    }
    if frame.header.communication_type != CommunicationType::Response {
        return Err(Malformed::CommunicationType(
            frame.header.communication_type,
        ));
    }
    if frame.header.message_type != request {
        return Err(Malformed::MessageType {
            expected: request,
            received: frame.header.message_type,
        });
    }
    Ok(())
}

/// Checks a response against the request it is paired with: [`check_header`], then the fields a
/// SUCCESS response repeats from its request. The manual: GET_GRASP's tool is "the tool of the
/// request (same value)", its pose is in the pose format the request asked for, and its object is
/// of the requested class unless that was 0 = any (3.3.3.1); GET_OBJECT_COUNT repeats the
/// requested class (3.3.4.1). These catch a response paired with another request of the same
/// type (a request lost on the wire, a corrupted counter) where the header cannot.
pub(crate) fn check_response(
    request: &RequestFrame,
    frame: &ResponseFrame,
) -> Result<(), Malformed> {
    let message_type = request.header.message_type;
    check_header(message_type, frame)?;
    if frame.header.response_code != ResponseCode::Success {
        // The rest of the body is meaningless (manual 3.2.2.2).
        return Ok(());
    }
    let differs = |field| {
        Err(Malformed::Echo {
            request: message_type,
            field,
        })
    };
    match message_type {
        MessageType::GetGrasp => {
            if frame.tool != request.tool {
                return differs("tool");
            }
            if frame.pose_format != request.pose_format {
                return differs("pose format");
            }
            if request.object_class != 0 && frame.object_class != request.object_class {
                return differs("object class");
            }
        }
        MessageType::GetObjectCount if frame.object_class != request.object_class => {
            return differs("object class");
        }
        _ => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::smartgrasp::types::ResponseCode;

    #[test]
    fn first_counter_is_learned_then_must_advance_by_one_and_wrap() {
        let mut p = Pairing::default();
        assert_eq!(p.counter(254, 1).unwrap().count, 0);
        assert_eq!(p.counter(255, 1).unwrap().count, 0);
        assert_eq!(p.counter(0, 1).unwrap().count, 0);
        assert_eq!(p.counter(1, 1).unwrap().count, 0);
    }

    #[test]
    fn a_gap_fails_the_oldest_requests_or_breaks_the_connection() {
        let mut p = Pairing::default();
        p.counter(10, 1).unwrap();
        // Two requests waiting (the first abandoned by a timeout); the response to the first
        // was lost: 12 arrives where 11 was due.
        assert_eq!(
            p.counter(12, 2).unwrap(),
            Lost {
                count: 1,
                first_expected: 11
            }
        );
        // One request waiting and a gap: nothing can explain it.
        assert!(matches!(
            p.counter(15, 1),
            Err(Error::ResponseLost {
                expected: 13,
                received: 15
            })
        ));
        // A repeated counter is a gap of 255.
        let mut p = Pairing::default();
        p.counter(0, 1).unwrap();
        assert!(p.counter(0, 3).is_err());
        // A gap across the wrap.
        let mut p = Pairing::default();
        p.counter(255, 1).unwrap();
        assert_eq!(p.counter(1, 2).unwrap().count, 1);
    }

    #[test]
    fn unsolicited_responses_are_refused() {
        assert!(matches!(
            Pairing::default().counter(0, 0),
            Err(Error::MalformedReply(Malformed::Unsolicited { counter: 0 }))
        ));
    }

    #[test]
    fn header_checks() {
        let ok = ResponseFrame::new(MessageType::GetObjectCount, ResponseCode::Success, 0);
        assert_eq!(check_header(MessageType::GetObjectCount, &ok), Ok(()));
        // Errata: the manual's table says 17 for GET_OBJECT_COUNT's response; it is 32.
        let mut wrong = ok;
        wrong.header.message_type = MessageType::GraspFeedback;
        assert!(matches!(
            check_header(MessageType::GetObjectCount, &wrong),
            Err(Malformed::MessageType { .. })
        ));
        let mut request = ok;
        request.header.communication_type = CommunicationType::Request;
        assert!(check_header(MessageType::GetObjectCount, &request).is_err());
        let mut v4 = ok;
        v4.version = 4;
        assert_eq!(
            check_header(MessageType::GetObjectCount, &v4),
            Err(Malformed::Version { version: 4 })
        );
    }

    #[test]
    fn success_responses_must_repeat_the_request() {
        use crate::smartgrasp::message::{GraspRequest, Request};
        use crate::smartgrasp::types::{GraspMode, PoseFormat, Tool};
        let count = Request::GetObjectCount { object_class: 2 }.to_frame();
        let mut ok = ResponseFrame::new(MessageType::GetObjectCount, ResponseCode::Success, 0);
        ok.object_class = 2;
        assert_eq!(check_response(&count, &ok), Ok(()));
        let mut other = ok;
        other.object_class = 1;
        assert!(matches!(
            check_response(&count, &other),
            Err(Malformed::Echo {
                field: "object class",
                ..
            })
        ));
        // Without SUCCESS the body means nothing and is not checked.
        other.header.response_code = ResponseCode::InvalidObjectClass;
        assert_eq!(check_response(&count, &other), Ok(()));

        let any = Request::GetGrasp(GraspRequest {
            grasp_mode: GraspMode::AutoGrasp,
            object_class: 0,
            tool: Tool::Exterior,
            pose_format: PoseFormat::Abc,
        })
        .to_frame();
        let mut grasp = ResponseFrame::new(MessageType::GetGrasp, ResponseCode::Success, 0);
        grasp.tool = Tool::Exterior;
        grasp.pose_format = PoseFormat::Abc;
        grasp.object_class = 7;
        assert_eq!(
            check_response(&any, &grasp),
            Ok(()),
            "class 0 asks for any class"
        );
        let mut class_one = any;
        class_one.object_class = 1;
        assert!(check_response(&class_one, &grasp).is_err());
        let mut suction = grasp;
        suction.tool = Tool::Contact;
        assert!(check_response(&any, &suction).is_err());
        let mut wpr = grasp;
        wpr.pose_format = PoseFormat::Wpr;
        assert!(check_response(&any, &wpr).is_err());
    }
}
