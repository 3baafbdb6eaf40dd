//! Pure pairing of responses to requests, with every check the protocol offers. No I/O: the task
//! feeds it, so each rule is tested on its own.
//!
//! Responses carry no request id; they come back in the order the requests were sent (one TCP
//! stream, one server loop), so pairing is in order. What the header offers is checked:
//! - communication type must be "response" and the prefix version the request's;
//! - the message type must be the request's (manual 3.3; errata: GET_OBJECT_COUNT answers 32);
//! - the response counter (manual 3.2.2.3) rises by one per response and wraps at 256. The manual
//!   does not say whether it counts per connection or across all of a server's clients (its own
//!   examples 6.4 and 6.5 both show 3; PROTOCOLS.md errata), so by default a gap is only
//!   *recorded* ([`Counted::gap`], a `tracing` warning and a count on the client): on TCP a gap
//!   does not mean a response was mispaired, and pairing rests on the order, the message type and
//!   the echoed fields. In strict mode ([`Pairing::strict`]) the counter is trusted: a gap of `k`
//!   means the `k` responses before this one were lost; with in-order delivery those belong to
//!   the `k` oldest waiting requests, which get [`Error::ResponseLost`] instead of someone else's
//!   answer, and a gap that no waiting request can explain breaks the connection. Either way the
//!   first response's counter is unknown to a fresh connection and is learned.
//! - the fields a SUCCESS response repeats from its request must match ([`check_response`]).
//!
//! What no check can see (V3 frames carry no checksum): a corrupted body byte that still makes a
//! valid value (a count, a pose, a server state, a response code) reaches the caller as it is.

use crate::smartgrasp::error::{Error, Malformed};
use crate::smartgrasp::frame::{AnyRequestFrame, AnyResponseFrame};
use crate::smartgrasp::types::{CommunicationType, MessageType, ResponseCode};

/// The response counter's expectations across a connection.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Pairing {
    /// The counter the next response should carry; `None` until the first response.
    next_counter: Option<u8>,
    /// Trust the counter: a gap charges the oldest waiting requests, or breaks the connection.
    strict: bool,
}

/// What [`Pairing::counter`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Counted {
    /// How many of the oldest waiting requests lost their response (strict mode only; 0 in the
    /// tolerant default).
    pub lost: usize,
    /// The counter this response should have carried.
    pub expected: u8,
    /// How many counter values were skipped (0: none).
    pub gap: u8,
}

impl Pairing {
    /// Pairing that trusts the response counter (see the module docs).
    pub(crate) fn strict() -> Pairing {
        Pairing {
            next_counter: None,
            strict: true,
        }
    }

    /// Whether the counter is trusted (see [`Pairing::strict`]).
    pub(crate) fn is_strict(&self) -> bool {
        self.strict
    }

    /// Checks the counter of a response that arrived while `waiting` requests (the abandoned ones
    /// included) were outstanding. `Ok`: in strict mode fail `lost` oldest requests with
    /// [`Error::ResponseLost`], then pair the response with the next; `gap` is what to record.
    /// `Err`: the connection must be closed.
    pub(crate) fn counter(&mut self, received: u8, waiting: usize) -> Result<Counted, Error> {
        if waiting == 0 {
            return Err(Malformed::Unsolicited { counter: received }.into());
        }
        let expected = self.next_counter.unwrap_or(received);
        let gap = received.wrapping_sub(expected);
        let lost = if self.strict {
            let lost = usize::from(gap);
            if lost >= waiting {
                return Err(Error::ResponseLost { expected, received });
            }
            lost
        } else {
            0
        };
        self.next_counter = Some(received.wrapping_add(1));
        Ok(Counted {
            lost,
            expected,
            gap,
        })
    }
}

/// Checks a response's prefix and header against the request it is paired with: the version the
/// request used (a server answers with it, manual 1.3), communication type "response", and a
/// message type that [`answers`] the request's.
pub(crate) fn check_header(
    request: &AnyRequestFrame,
    frame: &AnyResponseFrame,
) -> Result<(), Malformed> {
    if frame.version() != request.version() {
        return Err(Malformed::Version {
            version: frame.version(),
        });
    }
    let header = frame.header();
    if header.communication_type != CommunicationType::Response {
        return Err(Malformed::CommunicationType(header.communication_type));
    }
    let expected = request.header().message_type;
    // The erratum's 17 for a count is a V3 manual's table (3.3.4.1); V4 pins 32 (PROTOCOLS.md
    // 2b) and echoes no class that could tell a count from a GRASP_FEEDBACK response, so in V4
    // only the type itself answers (the explorer: after a dropped count response, the next
    // GRASP_FEEDBACK response was taken for the count, read as 0 objects).
    let fits = if request.version() >= 4 {
        expected == header.message_type
    } else {
        answers(expected, header.message_type)
    };
    if !fits {
        return Err(Malformed::MessageType {
            expected,
            received: header.message_type,
        });
    }
    Ok(())
}

/// Whether a response of type `response` may answer a request of type `request`: the same type,
/// or 17 for GET_OBJECT_COUNT. The manual's GET_OBJECT_COUNT response table (3.3.4.1) prints 17,
/// an erratum for 32 (17 is GRASP_FEEDBACK; PROTOCOLS.md), but a firmware that followed the
/// table would send 17, and refusing it would drop the connection on every count. The echoed
/// object class still tells a count from a feedback response where the class is not 0.
pub(crate) fn answers(request: MessageType, response: MessageType) -> bool {
    request == response
        || (request == MessageType::GetObjectCount && response == MessageType::GraspFeedback)
}

/// Whether a response to `a` could be taken for a response to `b` by its message type alone.
pub(crate) fn ambiguous(a: MessageType, b: MessageType) -> bool {
    answers(a, b) || answers(b, a) || {
        // Both could be answered with 17.
        let either = |t| t == MessageType::GetObjectCount || t == MessageType::GraspFeedback;
        either(a) && either(b)
    }
}

/// Checks a response against the request it is paired with: [`check_header`], then the fields a
/// SUCCESS V3 response repeats from its request. The manual: GET_GRASP's tool is "the tool of the
/// request (same value)", and its object is of the requested class unless that was 0 = any
/// (3.3.3.1); GET_OBJECT_COUNT repeats the requested class (3.3.4.1). GET_GRASP's pose format is
/// not an echo: it is the format "used for the pose field", whose type "depends on the value" of
/// it (3.3.3.1), so the pose is read in the format the response declares (and the client converts
/// it to the one its caller asked for; issue 21). These catch a response paired with another request of the same
/// type (a request lost on the wire, a corrupted counter) where the header cannot. V4 pins no
/// echo (PROTOCOLS.md 2b: the example reads no echoed field, and whether the class is echoed is
/// an open question), so a V4 response is checked by its header only.
pub(crate) fn check_response(
    request: &AnyRequestFrame,
    frame: &AnyResponseFrame,
) -> Result<(), Malformed> {
    check_header(request, frame)?;
    let (AnyRequestFrame::V3(request), AnyResponseFrame::V3(frame)) = (request, frame) else {
        return Ok(());
    };
    if frame.header.response_code != ResponseCode::Success {
        // The rest of the body is meaningless (manual 3.2.2.2).
        return Ok(());
    }
    let message_type = request.header.message_type;
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
    use crate::smartgrasp::frame::{v4, RequestFrame, ResponseFrame};
    use crate::smartgrasp::types::ResponseCode;

    fn v3_header(request: MessageType, frame: &ResponseFrame) -> Result<(), Malformed> {
        check_header(&RequestFrame::new(request).into(), &(*frame).into())
    }

    fn v3_response(request: &RequestFrame, frame: &ResponseFrame) -> Result<(), Malformed> {
        check_response(&(*request).into(), &(*frame).into())
    }

    #[test]
    fn a_response_must_use_the_requests_version_and_v4_pins_no_echo() {
        let v4_count = v4::RequestFrame::new(MessageType::GetObjectCount).into();
        let v3_answer = ResponseFrame::new(MessageType::GetObjectCount, ResponseCode::Success, 0);
        assert_eq!(
            check_response(&v4_count, &v3_answer.into()),
            Err(Malformed::Version { version: 3 })
        );
        let mut v4_answer =
            v4::ResponseFrame::new(MessageType::GetObjectCount, ResponseCode::Success, 0);
        v4_answer.object_id = 9;
        assert_eq!(check_response(&v4_count, &v4_answer.into()), Ok(()));
        let v3_count = RequestFrame::new(MessageType::GetObjectCount).into();
        assert_eq!(
            check_response(&v3_count, &v4_answer.into()),
            Err(Malformed::Version { version: 4 })
        );
    }

    #[test]
    fn first_counter_is_learned_then_must_advance_by_one_and_wrap() {
        for mut p in [Pairing::default(), Pairing::strict()] {
            for c in [254, 255, 0, 1] {
                let counted = p.counter(c, 1).unwrap();
                assert_eq!((counted.lost, counted.gap), (0, 0));
            }
        }
    }

    #[test]
    fn by_default_a_gap_is_recorded_and_charges_nobody() {
        let mut p = Pairing::default();
        p.counter(10, 1).unwrap();
        // A server counting across all its clients: 12 where 11 was due, one call waiting.
        assert_eq!(
            p.counter(12, 1).unwrap(),
            Counted {
                lost: 0,
                expected: 11,
                gap: 1
            }
        );
        // Learned from the last response: 13 is on time.
        assert_eq!(p.counter(13, 1).unwrap().gap, 0);
        // A repeated counter is a gap of 255, recorded too.
        assert_eq!(p.counter(13, 1).unwrap().gap, 255);
    }

    #[test]
    fn in_strict_mode_a_gap_fails_the_oldest_requests_or_breaks_the_connection() {
        let mut p = Pairing::strict();
        p.counter(10, 1).unwrap();
        // Two requests waiting (the first abandoned by a timeout); the response to the first
        // was lost: 12 arrives where 11 was due.
        assert_eq!(
            p.counter(12, 2).unwrap(),
            Counted {
                lost: 1,
                expected: 11,
                gap: 1
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
        let mut p = Pairing::strict();
        p.counter(0, 1).unwrap();
        assert!(p.counter(0, 3).is_err());
        // A gap across the wrap.
        let mut p = Pairing::strict();
        p.counter(255, 1).unwrap();
        assert_eq!(p.counter(1, 2).unwrap().lost, 1);
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
        assert_eq!(v3_header(MessageType::GetObjectCount, &ok), Ok(()));
        // Errata: the manual's table says 17 for GET_OBJECT_COUNT's response; it is 32, but a
        // server that follows the table is accepted.
        let mut seventeen = ok;
        seventeen.header.message_type = MessageType::GraspFeedback;
        assert_eq!(v3_header(MessageType::GetObjectCount, &seventeen), Ok(()));
        // Not the other way round, and no other type.
        assert!(matches!(
            v3_header(MessageType::GraspFeedback, &ok),
            Err(Malformed::MessageType { .. })
        ));
        let mut state = ok;
        state.header.message_type = MessageType::GetState;
        assert!(matches!(
            v3_header(MessageType::GetObjectCount, &state),
            Err(Malformed::MessageType { .. })
        ));
        assert!(ambiguous(
            MessageType::GraspFeedback,
            MessageType::GetObjectCount
        ));
        assert!(ambiguous(MessageType::GetGrasp, MessageType::GetGrasp));
        assert!(!ambiguous(
            MessageType::GetState,
            MessageType::GetObjectCount
        ));
        let mut request = ok;
        request.header.communication_type = CommunicationType::Request;
        assert!(v3_header(MessageType::GetObjectCount, &request).is_err());
        let mut v4 = ok;
        v4.version = 4;
        assert_eq!(
            v3_header(MessageType::GetObjectCount, &v4),
            Err(Malformed::Version { version: 4 })
        );
    }

    #[test]
    fn success_responses_must_repeat_the_request() {
        use crate::smartgrasp::message::{GraspRequest, Request};
        use crate::smartgrasp::types::{GraspMode, PoseFormat, SelectionCriterion, Tool};
        let count = Request::GetObjectCount { object_class: 2 }.to_frame();
        let mut ok = ResponseFrame::new(MessageType::GetObjectCount, ResponseCode::Success, 0);
        ok.object_class = 2;
        assert_eq!(v3_response(&count, &ok), Ok(()));
        let mut other = ok;
        other.object_class = 1;
        assert!(matches!(
            v3_response(&count, &other),
            Err(Malformed::Echo {
                field: "object class",
                ..
            })
        ));
        // Without SUCCESS the body means nothing and is not checked.
        other.header.response_code = ResponseCode::InvalidObjectClass;
        assert_eq!(v3_response(&count, &other), Ok(()));

        let any = Request::GetGrasp(GraspRequest {
            grasp_mode: GraspMode::AutoGrasp,
            object_class: 0,
            tool: Tool::Exterior,
            selection_criterion: SelectionCriterion::default(),
            pose_format: PoseFormat::Abc,
        })
        .to_frame();
        let mut grasp = ResponseFrame::new(MessageType::GetGrasp, ResponseCode::Success, 0);
        grasp.tool = Tool::Exterior;
        grasp.pose_format = PoseFormat::Abc;
        grasp.object_class = 7;
        assert_eq!(
            v3_response(&any, &grasp),
            Ok(()),
            "class 0 asks for any class"
        );
        let mut class_one = any;
        class_one.object_class = 1;
        assert!(v3_response(&class_one, &grasp).is_err());
        let mut suction = grasp;
        suction.tool = Tool::Contact;
        assert!(v3_response(&any, &suction).is_err());
        // The pose format says how to read the pose (3.3.3.1), it does not echo the request.
        let mut wpr = grasp;
        wpr.pose_format = PoseFormat::Wpr;
        assert_eq!(v3_response(&any, &wpr), Ok(()));
    }
}
