//! Typed commands and their one-line encoding (manual chapter 3). Pure: no I/O.
//!
//! Every argument is checked here, before anything is sent: floats must be finite and fit the
//! controller's 32-bit floats (manual 2.1.1), strings must be printable ASCII without `'`, `"`
//! and `\` and at most 32 characters, ports must be 0..=31. The encoded line never contains a
//! line feed, so no argument can inject a second command.

use std::fmt::Write as _;
use std::time::Duration;

use super::error::{Error, Result};
use super::value::{check_text, format_float, MAX_TEXT_LEN};

/// A port number: 0..PORTS-1 in the STANDALONE role, 0..=31 in the MASTER role (manual 2.6).
pub type PortNumber = u8;

/// The highest port number the protocol can address (MASTER role, manual 2.6).
pub const MAX_PORT: PortNumber = 31;

/// Whether a motion command holds its reply until the motion is done (`<do_block>`, manual
/// 3.4.4–3.4.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Blocking {
    /// Reply `ACK` as soon as the motion starts (the controller's default; `<do_block>` is left
    /// out). Wait for the end with WSTR or DEVSTATE.
    #[default]
    Immediate,
    /// Reply only when the motion is done (`<do_block>=1`). Later commands on the connection
    /// wait behind it.
    UntilDone,
}

/// FLEXGRIPF parameters in physical units (manual 3.4.6).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlexGrip {
    /// Target position, the no-part limit, in mm.
    pub position_mm: f64,
    /// Gripping force in N.
    pub force_n: f64,
    /// Gripping speed in mm/s; 0 = computed from the force.
    pub speed_mm_per_s: f64,
    /// Acceleration in mm/s²; 0 = the device's default.
    pub acceleration_mm_per_s2: f64,
}

/// FLEXGRIP parameters as scaled integers (manual 3.4.6: 1/1000 of mm, N, mm/s, mm/s²).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FlexGripScaled {
    /// Target position, the no-part limit, in µm.
    pub position_um: i32,
    /// Gripping force in mN.
    pub force_mn: i32,
    /// Gripping speed in µm/s; 0 = computed from the force.
    pub speed_um_per_s: i32,
    /// Acceleration in µm/s²; 0 = the device's default.
    pub acceleration_um_per_s2: i32,
}

/// FLEXRELEASEF parameters in physical units (manual 3.4.7).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlexRelease {
    /// Target position, the release limit, in mm.
    pub position_mm: f64,
    /// Release speed in mm/s; 0 = the device's default.
    pub speed_mm_per_s: f64,
    /// Acceleration in mm/s²; 0 = the device's default.
    pub acceleration_mm_per_s2: f64,
}

/// FLEXRELEASE parameters as scaled integers (manual 3.4.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FlexReleaseScaled {
    /// Target position, the release limit, in µm.
    pub position_um: i32,
    /// Release speed in µm/s; 0 = the device's default.
    pub speed_um_per_s: i32,
    /// Acceleration in µm/s²; 0 = the device's default.
    pub acceleration_um_per_s2: i32,
}

/// A grip recipe with scaled integer parameters (GRIPCFG, manual 3.6.1).
///
/// For Weiss grippers: `params[0]` no-part limit in µm, `params[1]` release limit in µm,
/// `params[2]` force factor in 1/1000 % (0..=100000); on WPG grippers `params[3..=6]` are grip
/// speed (µm/s), grip acceleration (µm/s²), release speed, release acceleration; the rest 0.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct GripConfig {
    /// The recipe's name (at most 32 characters).
    pub tag: String,
    /// The eight device-specific parameters.
    pub params: [i32; 8],
}

/// A grip recipe with float parameters (GRIPCFGF, manual 3.6.1).
///
/// For Weiss grippers: `params[0]` no-part limit in mm, `params[1]` release limit in mm,
/// `params[2]` force factor in % (0..=100); on WPG grippers `params[3..=6]` are grip speed
/// (mm/s), grip acceleration (mm/s²), release speed, release acceleration; the rest 0.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GripConfigF {
    /// The recipe's name (at most 32 characters).
    pub tag: String,
    /// The eight device-specific parameters.
    pub params: [f64; 8],
}

impl GripConfigF {
    /// A Weiss gripper recipe: no-part limit, release limit and force factor; the rest 0.
    pub fn gripper(
        tag: impl Into<String>,
        no_part_limit_mm: f64,
        release_limit_mm: f64,
        force_percent: f64,
    ) -> Self {
        let mut params = [0.0; 8];
        params[0] = no_part_limit_mm;
        params[1] = release_limit_mm;
        params[2] = force_percent;
        GripConfigF {
            tag: tag.into(),
            params,
        }
    }
}

/// Every command of the GRIPLINK Unified Command Set (manual chapter 3).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Command {
    /// `ID?` (3.1.1).
    Id,
    /// `PROTOCOL?` (3.1.2).
    Protocol,
    /// `PROTASSERT("<identifier>",<min_version>)` (3.1.3).
    ProtAssert {
        /// Protocol identifier, e.g. `GRIPLINK`.
        identifier: String,
        /// Minimum protocol version.
        min_version: u32,
    },
    /// `SN?` (3.1.4).
    SerialNumber,
    /// `LABEL?` (3.1.5).
    Label,
    /// `LABEL="<label>"` (3.1.5).
    SetLabel(String),
    /// `VER?` (3.1.6).
    Version,
    /// `VERBOSE=<0|1>` (3.1.7).
    SetVerbose(bool),
    /// `DEVVID[p]?` (3.2.1).
    DevVid(PortNumber),
    /// `DEVPID[p]?` (3.2.2).
    DevPid(PortNumber),
    /// `DEVASSERT(p,vid,pid)` (3.2.3).
    DevAssert {
        /// Port.
        port: PortNumber,
        /// Expected vendor id.
        vendor_id: u32,
        /// Expected product id.
        product_id: u32,
    },
    /// `DEVNAME[p]?` (3.2.4).
    DevName(PortNumber),
    /// `DEVVENDOR[p]?` (3.2.5).
    DevVendor(PortNumber),
    /// `DEVSN[p]?` (3.2.6).
    DevSn(PortNumber),
    /// `DEVTAG[p]?` (3.2.7).
    DevTag(PortNumber),
    /// `DEVTAG[p]="<tag>"` (3.2.7).
    SetDevTag(PortNumber, String),
    /// `DEVVER[p]?` (3.2.8).
    DevVer(PortNumber),
    /// `BYE()` (3.3.1).
    Bye,
    /// `ENABLE(p)` (3.4.1).
    Enable(PortNumber),
    /// `DISABLE(p)` (3.4.2).
    Disable(PortNumber),
    /// `HOME(p)`, blocks until done (3.4.3).
    Home(PortNumber),
    /// `GRIP(p,index[,1])` (3.4.4).
    Grip {
        /// Port.
        port: PortNumber,
        /// Grip recipe index.
        index: u32,
        /// Whether the reply waits for the end of the motion.
        blocking: Blocking,
    },
    /// `RELEASE(p,index[,1])` (3.4.5).
    Release {
        /// Port.
        port: PortNumber,
        /// Grip recipe index.
        index: u32,
        /// Whether the reply waits for the end of the motion.
        blocking: Blocking,
    },
    /// `FLEXGRIP(p,pos,force,speed,acc[,1])` (3.4.6).
    FlexGrip(PortNumber, FlexGripScaled, Blocking),
    /// `FLEXGRIPF(p,pos,force,speed,acc[,1])` (3.4.6).
    FlexGripF(PortNumber, FlexGrip, Blocking),
    /// `FLEXRELEASE(p,pos,speed,acc[,1])` (3.4.7).
    FlexRelease(PortNumber, FlexReleaseScaled, Blocking),
    /// `FLEXRELEASEF(p,pos,speed,acc[,1])` (3.4.7).
    FlexReleaseF(PortNumber, FlexRelease, Blocking),
    /// `LED(p,index)` (3.4.8).
    Led {
        /// Port.
        port: PortNumber,
        /// Animation index.
        index: u32,
    },
    /// `CLAMP(p,0|1)` (3.4.9).
    Clamp {
        /// Port.
        port: PortNumber,
        /// Force retention on or off.
        enable: bool,
    },
    /// `WSTR[p]?`: waits for a state transition (3.4.10).
    Wstr(PortNumber),
    /// `SETVAL(p,index,value)` (3.4.11).
    SetVal {
        /// Port.
        port: PortNumber,
        /// Value index.
        index: u32,
        /// Scaled integer value.
        value: i32,
    },
    /// `SETVALF(p,index,value)` (3.4.11).
    SetValF {
        /// Port.
        port: PortNumber,
        /// Value index.
        index: u32,
        /// Value in the device's unit.
        value: f64,
    },
    /// `WAITVAL(p,index,threshold,window,timeout_ms)` (3.4.12).
    WaitVal {
        /// Port.
        port: PortNumber,
        /// Value index.
        index: u32,
        /// Scaled threshold.
        threshold: i32,
        /// Scaled window size around the threshold.
        window: i32,
        /// The controller-side timeout (sent in ms).
        timeout: Duration,
    },
    /// `WAITVALF(p,index,threshold,window,timeout_ms)` (3.4.12).
    WaitValF {
        /// Port.
        port: PortNumber,
        /// Value index.
        index: u32,
        /// Threshold in the device's unit.
        threshold: f64,
        /// Window size in the device's unit.
        window: f64,
        /// The controller-side timeout (sent in ms).
        timeout: Duration,
    },
    /// `DEVSTATE[p]?` (3.5.1).
    DevState(PortNumber),
    /// `VALUE[p][index]?` (3.5.2).
    Value {
        /// Port.
        port: PortNumber,
        /// Value index (0 = finger position on grippers).
        index: u32,
    },
    /// `VALUEF[p][index]?` (3.5.2).
    ValueF {
        /// Port.
        port: PortNumber,
        /// Value index (0 = finger position on grippers).
        index: u32,
    },
    /// `GRIPCFG[p][index]?` (3.6.1).
    GripCfg {
        /// Port.
        port: PortNumber,
        /// Recipe index.
        index: u32,
    },
    /// `GRIPCFG[p][index]=[…]` (3.6.1).
    SetGripCfg {
        /// Port.
        port: PortNumber,
        /// Recipe index.
        index: u32,
        /// The recipe.
        config: GripConfig,
    },
    /// `GRIPCFGF[p][index]?` (3.6.1).
    GripCfgF {
        /// Port.
        port: PortNumber,
        /// Recipe index.
        index: u32,
    },
    /// `GRIPCFGF[p][index]=[…]` (3.6.1).
    SetGripCfgF {
        /// Port.
        port: PortNumber,
        /// Recipe index.
        index: u32,
        /// The recipe.
        config: GripConfigF,
    },
}

/// The reply a command must get (besides `ERR …`, which any command can get).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// `ACK`.
    Ack,
    /// `KEY[port][index]=value`, with as many indices as given.
    Data {
        /// The key (`DEVSTATE`).
        key: &'static str,
        /// The port in brackets, if the key has one.
        port: Option<PortNumber>,
        /// The second index in brackets, if the key has one.
        index: Option<u32>,
    },
    /// Anything well-formed (raw commands).
    Any,
}

/// How long a command may legitimately take, which picks its default timeout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Duty {
    /// Answered at once.
    Query,
    /// Holds its reply until a motion or state transition is done (HOME, blocking GRIP/RELEASE/
    /// FLEX…, WSTR).
    Motion,
    /// WAITVAL: holds its reply for at most its own timeout.
    Wait(Duration),
}

/// `KEY[i]…?`, the query of a keyed value (manual 2.1). Written by hand rather than with
/// `write!`: queries are what a program sends most often (polling a position or a state), and
/// the formatting machinery cost more than the rest of a call's encoding and decoding together.
fn push_query(s: &mut String, key: &str, indices: &[u32]) {
    s.push_str(key);
    for index in indices {
        s.push('[');
        push_decimal(s, *index);
        s.push(']');
    }
    s.push('?');
}

/// `n` in decimal, as `{n}` formats it.
fn push_decimal(s: &mut String, n: u32) {
    // Filled from the right; a u32 has at most 10 digits.
    let mut digits = [0u8; 10];
    let mut len = 0;
    let mut rest = n;
    for slot in digits.iter_mut().rev() {
        *slot = b'0' + (rest % 10) as u8;
        len += 1;
        rest /= 10;
        if rest == 0 {
            break;
        }
    }
    let first = digits.len() - len;
    s.extend(digits.iter().skip(first).map(|d| char::from(*d)));
}

fn check_port(port: PortNumber) -> Result<()> {
    if port > MAX_PORT {
        return Err(Error::invalid(
            "port",
            format!("{port} is above {MAX_PORT}, the highest port of the protocol"),
        ));
    }
    Ok(())
}

fn check_string(what: &'static str, text: &str) -> Result<()> {
    check_text(text, MAX_TEXT_LEN).map_err(|e| Error::invalid(what, e.to_string()))
}

/// Longest plain decimal a float argument of a typed command can take: a sign, `0.`, 37 zeros
/// and 17 significant digits just above `f32::MIN_POSITIVE`; 39 digits at `f32::MAX`. Smaller
/// (but not 0) and larger magnitudes are refused before formatting ([`Command::encode`]). Eight
/// floats (GRIPCFGF) and a 32-character tag stay far below the 1024-byte line bound.
pub const MAX_FLOAT_ARG_LEN: usize = 57;

/// Formats a float argument: finite and within the controller's 32-bit float range (manual
/// 2.1.1), as a plain decimal.
///
/// Checked before formatting: a plain decimal has no exponent, so a tiny magnitude such as
/// `1e-300` would need hundreds of digits (over the line bound with a few of them) for a value
/// the controller's 32-bit float cannot hold anyway. Magnitudes below `f32::MIN_POSITIVE`
/// (about 1.2e-38) other than 0 are refused, as those above `f32::MAX` are.
pub(crate) fn float_arg(what: &'static str, value: f64) -> Result<String> {
    if !value.is_finite() {
        return Err(Error::invalid(
            what,
            format!("{value} is not a finite number"),
        ));
    }
    if value.abs() > f64::from(f32::MAX) {
        return Err(Error::invalid(
            what,
            format!("{value:e} does not fit the controller's 32-bit float"),
        ));
    }
    if value != 0.0 && value.abs() < f64::from(f32::MIN_POSITIVE) {
        let digits = -value.abs().log10().floor();
        return Err(Error::invalid(
            what,
            format!(
                "{value:e} is too close to 0 for the controller's 32-bit float; as a plain \
                 decimal (no exponent, manual 2.1.1) it would need over {digits} digits: send 0"
            ),
        ));
    }
    format_float(value).ok_or_else(|| Error::invalid(what, "not a finite number"))
}

fn wait_timeout_ms(timeout: Duration) -> Result<u128> {
    let ms = timeout.as_millis();
    if ms > i32::MAX as u128 {
        return Err(Error::invalid(
            "timeout",
            format!("{timeout:?} is above the controller's 32-bit milliseconds"),
        ));
    }
    Ok(ms)
}

fn block_suffix(blocking: Blocking) -> &'static str {
    match blocking {
        Blocking::Immediate => "",
        Blocking::UntilDone => ",1",
    }
}

impl Command {
    /// The port this command addresses, if any.
    pub fn port(&self) -> Option<PortNumber> {
        use Command::*;
        match self {
            Id
            | Protocol
            | ProtAssert { .. }
            | SerialNumber
            | Label
            | SetLabel(_)
            | Version
            | SetVerbose(_)
            | Bye => None,
            DevVid(p)
            | DevPid(p)
            | DevName(p)
            | DevVendor(p)
            | DevSn(p)
            | DevTag(p)
            | SetDevTag(p, _)
            | DevVer(p)
            | Enable(p)
            | Disable(p)
            | Home(p)
            | Wstr(p)
            | DevState(p)
            | FlexGrip(p, ..)
            | FlexGripF(p, ..)
            | FlexRelease(p, ..)
            | FlexReleaseF(p, ..) => Some(*p),
            DevAssert { port, .. }
            | Grip { port, .. }
            | Release { port, .. }
            | Led { port, .. }
            | Clamp { port, .. }
            | SetVal { port, .. }
            | SetValF { port, .. }
            | WaitVal { port, .. }
            | WaitValF { port, .. }
            | Value { port, .. }
            | ValueF { port, .. }
            | GripCfg { port, .. }
            | SetGripCfg { port, .. }
            | GripCfgF { port, .. }
            | SetGripCfgF { port, .. } => Some(*port),
        }
    }

    /// The command as one line, upper case, **without** the terminating LF (the codec adds it).
    /// Refuses invalid arguments before anything is sent: among them floats that are not
    /// finite or whose magnitude the controller's 32-bit float cannot hold (above `f32::MAX`,
    /// or below `f32::MIN_POSITIVE` but not 0: hundreds of digits as a plain decimal).
    pub fn encode(&self) -> Result<String> {
        use Command::*;
        if let Some(port) = self.port() {
            check_port(port)?;
        }
        let mut s = String::with_capacity(48);
        // `write!` into a String cannot fail; the results are ignored for that reason.
        match self {
            Id => s.push_str("ID?"),
            Protocol => s.push_str("PROTOCOL?"),
            ProtAssert {
                identifier,
                min_version,
            } => {
                check_string("protocol identifier", identifier)?;
                let _ = write!(s, "PROTASSERT(\"{identifier}\",{min_version})");
            }
            SerialNumber => s.push_str("SN?"),
            Label => s.push_str("LABEL?"),
            SetLabel(label) => {
                check_string("label", label)?;
                let _ = write!(s, "LABEL=\"{label}\"");
            }
            Version => s.push_str("VER?"),
            SetVerbose(on) => {
                let _ = write!(s, "VERBOSE={}", u8::from(*on));
            }
            DevVid(p) => push_query(&mut s, "DEVVID", &[u32::from(*p)]),
            DevPid(p) => push_query(&mut s, "DEVPID", &[u32::from(*p)]),
            DevAssert {
                port,
                vendor_id,
                product_id,
            } => {
                let _ = write!(s, "DEVASSERT({port},{vendor_id},{product_id})");
            }
            DevName(p) => push_query(&mut s, "DEVNAME", &[u32::from(*p)]),
            DevVendor(p) => push_query(&mut s, "DEVVENDOR", &[u32::from(*p)]),
            DevSn(p) => push_query(&mut s, "DEVSN", &[u32::from(*p)]),
            DevTag(p) => push_query(&mut s, "DEVTAG", &[u32::from(*p)]),
            SetDevTag(p, tag) => {
                check_string("device tag", tag)?;
                let _ = write!(s, "DEVTAG[{p}]=\"{tag}\"");
            }
            DevVer(p) => push_query(&mut s, "DEVVER", &[u32::from(*p)]),
            Bye => s.push_str("BYE()"),
            Enable(p) => {
                let _ = write!(s, "ENABLE({p})");
            }
            Disable(p) => {
                let _ = write!(s, "DISABLE({p})");
            }
            Home(p) => {
                let _ = write!(s, "HOME({p})");
            }
            Grip {
                port,
                index,
                blocking,
            } => {
                let _ = write!(s, "GRIP({port},{index}{})", block_suffix(*blocking));
            }
            Release {
                port,
                index,
                blocking,
            } => {
                let _ = write!(s, "RELEASE({port},{index}{})", block_suffix(*blocking));
            }
            FlexGrip(p, a, b) => {
                let _ = write!(
                    s,
                    "FLEXGRIP({p},{},{},{},{}{})",
                    a.position_um,
                    a.force_mn,
                    a.speed_um_per_s,
                    a.acceleration_um_per_s2,
                    block_suffix(*b)
                );
            }
            FlexGripF(p, a, b) => {
                let _ = write!(
                    s,
                    "FLEXGRIPF({p},{},{},{},{}{})",
                    float_arg("position_mm", a.position_mm)?,
                    float_arg("force_n", a.force_n)?,
                    float_arg("speed_mm_per_s", a.speed_mm_per_s)?,
                    float_arg("acceleration_mm_per_s2", a.acceleration_mm_per_s2)?,
                    block_suffix(*b)
                );
            }
            FlexRelease(p, a, b) => {
                let _ = write!(
                    s,
                    "FLEXRELEASE({p},{},{},{}{})",
                    a.position_um,
                    a.speed_um_per_s,
                    a.acceleration_um_per_s2,
                    block_suffix(*b)
                );
            }
            FlexReleaseF(p, a, b) => {
                let _ = write!(
                    s,
                    "FLEXRELEASEF({p},{},{},{}{})",
                    float_arg("position_mm", a.position_mm)?,
                    float_arg("speed_mm_per_s", a.speed_mm_per_s)?,
                    float_arg("acceleration_mm_per_s2", a.acceleration_mm_per_s2)?,
                    block_suffix(*b)
                );
            }
            Led { port, index } => {
                let _ = write!(s, "LED({port},{index})");
            }
            Clamp { port, enable } => {
                let _ = write!(s, "CLAMP({port},{})", u8::from(*enable));
            }
            Wstr(p) => push_query(&mut s, "WSTR", &[u32::from(*p)]),
            SetVal { port, index, value } => {
                let _ = write!(s, "SETVAL({port},{index},{value})");
            }
            SetValF { port, index, value } => {
                let _ = write!(s, "SETVALF({port},{index},{})", float_arg("value", *value)?);
            }
            WaitVal {
                port,
                index,
                threshold,
                window,
                timeout,
            } => {
                let ms = wait_timeout_ms(*timeout)?;
                let _ = write!(s, "WAITVAL({port},{index},{threshold},{window},{ms})");
            }
            WaitValF {
                port,
                index,
                threshold,
                window,
                timeout,
            } => {
                let ms = wait_timeout_ms(*timeout)?;
                let _ = write!(
                    s,
                    "WAITVALF({port},{index},{},{},{ms})",
                    float_arg("threshold", *threshold)?,
                    float_arg("window", *window)?
                );
            }
            DevState(p) => push_query(&mut s, "DEVSTATE", &[u32::from(*p)]),
            Value { port, index } => {
                push_query(&mut s, "VALUE", &[u32::from(*port), *index]);
            }
            ValueF { port, index } => {
                push_query(&mut s, "VALUEF", &[u32::from(*port), *index]);
            }
            GripCfg { port, index } => {
                push_query(&mut s, "GRIPCFG", &[u32::from(*port), *index]);
            }
            SetGripCfg {
                port,
                index,
                config,
            } => {
                check_string("recipe tag", &config.tag)?;
                let _ = write!(s, "GRIPCFG[{port}][{index}]=[\"{}\"", config.tag);
                for p in config.params {
                    let _ = write!(s, ",{p}");
                }
                s.push(']');
            }
            GripCfgF { port, index } => {
                push_query(&mut s, "GRIPCFGF", &[u32::from(*port), *index]);
            }
            SetGripCfgF {
                port,
                index,
                config,
            } => {
                check_string("recipe tag", &config.tag)?;
                let _ = write!(s, "GRIPCFGF[{port}][{index}]=[\"{}\"", config.tag);
                for p in config.params {
                    let _ = write!(s, ",{}", float_arg("recipe parameter", p)?);
                }
                s.push(']');
            }
        }
        Ok(s)
    }

    /// The reply this command must get.
    pub fn expect(&self) -> Expect {
        use Command::*;
        let data = |key, port, index| Expect::Data { key, port, index };
        match self {
            Id => data("ID", None, None),
            Protocol => data("PROTOCOL", None, None),
            SerialNumber => data("SN", None, None),
            Label | SetLabel(_) => data("LABEL", None, None),
            Version => data("VER", None, None),
            SetVerbose(_) => data("VERBOSE", None, None),
            DevVid(p) => data("DEVVID", Some(*p), None),
            DevPid(p) => data("DEVPID", Some(*p), None),
            DevName(p) => data("DEVNAME", Some(*p), None),
            DevVendor(p) => data("DEVVENDOR", Some(*p), None),
            DevSn(p) => data("DEVSN", Some(*p), None),
            DevTag(p) | SetDevTag(p, _) => data("DEVTAG", Some(*p), None),
            DevVer(p) => data("DEVVER", Some(*p), None),
            Wstr(p) => data("WSTR", Some(*p), None),
            DevState(p) => data("DEVSTATE", Some(*p), None),
            Value { port, index } => data("VALUE", Some(*port), Some(*index)),
            ValueF { port, index } => data("VALUEF", Some(*port), Some(*index)),
            GripCfg { port, index } | SetGripCfg { port, index, .. } => {
                data("GRIPCFG", Some(*port), Some(*index))
            }
            GripCfgF { port, index } | SetGripCfgF { port, index, .. } => {
                data("GRIPCFGF", Some(*port), Some(*index))
            }
            ProtAssert { .. }
            | DevAssert { .. }
            | Bye
            | Enable(_)
            | Disable(_)
            | Home(_)
            | Grip { .. }
            | Release { .. }
            | FlexGrip(..)
            | FlexGripF(..)
            | FlexRelease(..)
            | FlexReleaseF(..)
            | Led { .. }
            | Clamp { .. }
            | SetVal { .. }
            | SetValF { .. }
            | WaitVal { .. }
            | WaitValF { .. } => Expect::Ack,
        }
    }

    /// How long the controller may legitimately hold the reply (picks the default timeout).
    pub(crate) fn duty(&self) -> Duty {
        use Command::*;
        match self {
            Home(_) | Wstr(_) => Duty::Motion,
            Grip { blocking, .. } | Release { blocking, .. } => blocking_duty(*blocking),
            FlexGrip(_, _, b)
            | FlexGripF(_, _, b)
            | FlexRelease(_, _, b)
            | FlexReleaseF(_, _, b) => blocking_duty(*b),
            WaitVal { timeout, .. } | WaitValF { timeout, .. } => Duty::Wait(*timeout),
            _ => Duty::Query,
        }
    }
}

fn blocking_duty(blocking: Blocking) -> Duty {
    match blocking {
        Blocking::Immediate => Duty::Query,
        Blocking::UntilDone => Duty::Motion,
    }
}

/// Checks a raw command line for [`Client::command`](super::Client::command): printable ASCII
/// only, no control characters (so no LF: one line is one command), not empty and not only
/// spaces (the controller trims a command, manual 2.1: a blank line would be no command, get
/// no reply, and the call would wait for one that never comes).
pub(crate) fn check_raw_line(line: &str) -> Result<()> {
    if line.is_empty() {
        return Err(Error::invalid("command line", "empty"));
    }
    if line.bytes().all(|b| b == b' ') {
        return Err(Error::invalid(
            "command line",
            "only spaces: the controller trims it to nothing and never answers",
        ));
    }
    if let Some((at, ch)) = line
        .chars()
        .enumerate()
        .find(|(_, c)| !(c.is_ascii() && (0x20..=0x7E).contains(&(*c as u32))))
    {
        return Err(Error::invalid(
            "command line",
            format!("character {ch:?} at {at} is not printable ASCII"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enc(c: Command) -> String {
        c.encode().unwrap()
    }

    #[test]
    fn queries_write_their_indices_as_format_does() {
        for n in [0, 7, 9, 10, 31, 99, 100, 4096, 1_000_000_000, u32::MAX] {
            let mut s = String::new();
            push_query(&mut s, "VALUE", &[n, n / 7]);
            assert_eq!(s, format!("VALUE[{n}][{}]?", n / 7));
        }
        assert_eq!(enc(Command::DevState(31)), "DEVSTATE[31]?");
        assert_eq!(
            enc(Command::GripCfgF {
                port: 2,
                index: 123
            }),
            "GRIPCFGF[2][123]?"
        );
    }

    #[test]
    fn manual_examples() {
        assert_eq!(enc(Command::Id), "ID?");
        assert_eq!(
            enc(Command::ProtAssert {
                identifier: "GRIPLINK".into(),
                min_version: 2
            }),
            "PROTASSERT(\"GRIPLINK\",2)"
        );
        assert_eq!(enc(Command::SetLabel("Marvin".into())), "LABEL=\"Marvin\"");
        assert_eq!(enc(Command::SetVerbose(true)), "VERBOSE=1");
        assert_eq!(enc(Command::DevVid(2)), "DEVVID[2]?");
        assert_eq!(
            enc(Command::DevAssert {
                port: 0,
                vendor_id: 815,
                product_id: 20
            }),
            "DEVASSERT(0,815,20)"
        );
        assert_eq!(
            enc(Command::SetDevTag(1, "Device 1".into())),
            "DEVTAG[1]=\"Device 1\""
        );
        assert_eq!(
            enc(Command::Grip {
                port: 2,
                index: 3,
                blocking: Blocking::Immediate
            }),
            "GRIP(2,3)"
        );
        assert_eq!(
            enc(Command::Release {
                port: 2,
                index: 3,
                blocking: Blocking::UntilDone
            }),
            "RELEASE(2,3,1)"
        );
        let flex = FlexGrip {
            position_mm: 15.0,
            force_n: 60.0,
            speed_mm_per_s: 45.5,
            acceleration_mm_per_s2: 0.0,
        };
        assert_eq!(
            enc(Command::FlexGripF(2, flex, Blocking::Immediate)),
            "FLEXGRIPF(2,15,60,45.5,0)"
        );
        let scaled = FlexGripScaled {
            position_um: 15000,
            force_mn: 60000,
            speed_um_per_s: 45500,
            acceleration_um_per_s2: 0,
        };
        assert_eq!(
            enc(Command::FlexGrip(2, scaled, Blocking::UntilDone)),
            "FLEXGRIP(2,15000,60000,45500,0,1)"
        );
        let rel = FlexRelease {
            position_mm: 19.5,
            ..Default::default()
        };
        assert_eq!(
            enc(Command::FlexReleaseF(2, rel, Blocking::UntilDone)),
            "FLEXRELEASEF(2,19.5,0,0,1)"
        );
        assert_eq!(
            enc(Command::SetValF {
                port: 0,
                index: 1,
                value: 42.3
            }),
            "SETVALF(0,1,42.3)"
        );
        assert_eq!(
            enc(Command::WaitVal {
                port: 0,
                index: 0,
                threshold: 300000,
                window: 50000,
                timeout: Duration::from_secs(10)
            }),
            "WAITVAL(0,0,300000,50000,10000)"
        );
        assert_eq!(enc(Command::ValueF { port: 0, index: 0 }), "VALUEF[0][0]?");
        assert_eq!(
            enc(Command::SetGripCfg {
                port: 1,
                index: 0,
                config: GripConfig {
                    tag: "tube".into(),
                    params: [3500, 10800, 50000, 0, 0, 0, 0, 0]
                }
            }),
            "GRIPCFG[1][0]=[\"tube\",3500,10800,50000,0,0,0,0,0]"
        );
        assert_eq!(
            enc(Command::SetGripCfgF {
                port: 1,
                index: 0,
                config: GripConfigF::gripper("tube", 3.5, 10.8, 50.0)
            }),
            "GRIPCFGF[1][0]=[\"tube\",3.5,10.8,50,0,0,0,0,0]"
        );
        assert_eq!(enc(Command::Bye), "BYE()");
    }

    #[test]
    fn refused_before_sending() {
        assert!(Command::SetLabel("a\nDISABLE(0)".into()).encode().is_err());
        assert!(Command::SetLabel("x".repeat(33)).encode().is_err());
        assert!(Command::SetDevTag(0, "it's".into()).encode().is_err());
        assert!(Command::DevState(32).encode().is_err());
        let nan = FlexGrip {
            position_mm: f64::NAN,
            ..Default::default()
        };
        assert!(Command::FlexGripF(0, nan, Blocking::Immediate)
            .encode()
            .is_err());
        assert!(Command::SetValF {
            port: 0,
            index: 0,
            value: f64::INFINITY
        }
        .encode()
        .is_err());
        assert!(Command::SetValF {
            port: 0,
            index: 0,
            value: 1e39
        }
        .encode()
        .is_err());
        assert_eq!(
            enc(Command::SetValF {
                port: 0,
                index: 0,
                value: 1e-7
            }),
            "SETVALF(0,0,0.0000001)"
        );
        assert!(check_raw_line("ID?").is_ok());
        assert!(check_raw_line("ID?\nBYE()").is_err());
        assert!(check_raw_line("ID?\r").is_err());
        assert!(check_raw_line("").is_err());
        assert!(check_raw_line("   ").is_err());
        assert!(check_raw_line(" ID? ").is_ok());
        // Tiny magnitudes are refused before formatting; the extremes accepted stay short.
        assert!(float_arg("value", 1e-300).is_err());
        assert!(float_arg("value", -1e-39).is_err());
        assert_eq!(float_arg("value", 0.0).unwrap(), "0");
        let smallest = -f64::from(f32::MIN_POSITIVE) * 1.000_000_000_000_1;
        let largest = -f64::from(f32::MAX);
        for v in [smallest, largest] {
            let text = float_arg("value", v).unwrap();
            assert!(
                text.len() <= MAX_FLOAT_ARG_LEN,
                "{text} ({} chars)",
                text.len()
            );
        }
    }
}
