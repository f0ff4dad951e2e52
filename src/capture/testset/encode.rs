//! `--encode`: how the three written inputs encode their linear signal, and the curve
//! recorded for them (`encoding.toml`).

use super::*;

/// How the three written inputs encode their linear signal (`--encode`). The ground truth is
/// merged from the linearised frames; only the inputs' merge takes its weights from the
/// reference as written.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum EncodeSpec {
    /// `device` for JPEG/PNG/TIFF frames; `field` for DNG frames (linear raw has no device
    /// curve).
    #[default]
    Auto,
    /// linear^(1/2.2), the field's convention (Kalantari, Wu: LDR^γ recovers the linear frame).
    Field,
    /// The device's own codes as stored; their response is the linearisation's (an estimated
    /// response's codes are mapped onto one curve channel by channel: [`EncodePlan::resolve`]).
    Device,
    /// Re-encoded with a profile's device response (the curve a network was fine-tuned on).
    Profile(PathBuf),
}

impl std::str::FromStr for EncodeSpec {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<EncodeSpec, String> {
        match s.trim() {
            "auto" => Ok(EncodeSpec::Auto),
            "field" => Ok(EncodeSpec::Field),
            "device" => Ok(EncodeSpec::Device),
            t => match t.strip_prefix("profile:") {
                Some(p) if !p.is_empty() => Ok(EncodeSpec::Profile(PathBuf::from(p))),
                _ => Err(format!(
                    "'{s}': expected auto, device (the frames' own codes), field (linear^(1/2.2)) \
                     or profile:PATH (a sensor profile's device response)"
                )),
            },
        }
    }
}

/// [`EncodeSpec`] resolved against the scanned frames.
#[derive(Clone, Debug, PartialEq)]
pub enum Encode {
    Field,
    Device,
    Curve(Response),
}

/// The encoding `spec` asks for on `sets`, checked before any work (a profile that does not
/// load, device codes of DNG frames: refused, naming the file); [`EncodePlan::resolve`] finishes
/// it once the linearisation is known.
pub fn plan_encoding(spec: &EncodeSpec, sets: &[scan::BracketSet]) -> Result<EncodePlan> {
    let frames = || sets.iter().flat_map(|s| &s.frames);
    let dng = frames().find(|f| f.kind == FrameKind::Dng);
    let ldr = frames().find(|f| f.kind == FrameKind::Ldr);
    let refuse_dng = |f: &BracketFrame, asked: &str| {
        Error::layout(
            &f.path,
            format!(
                "{asked}: a DNG holds linear raw values, not a device's codes; give --encode \
                 field (linear^(1/2.2)) or --encode profile:PATH (a profile's response)"
            ),
        )
    };
    Ok(match spec {
        EncodeSpec::Field => EncodePlan::Field,
        EncodeSpec::Auto => match (dng, ldr) {
            (Some(d), Some(_)) => {
                return Err(refuse_dng(
                    d,
                    "--encode auto on a folder of DNG and JPEG/PNG/TIFF sets",
                ));
            }
            (Some(_), None) => EncodePlan::Field,
            _ => EncodePlan::Device,
        },
        EncodeSpec::Device => match dng {
            Some(d) => return Err(refuse_dng(d, "--encode device")),
            None => EncodePlan::Device,
        },
        EncodeSpec::Profile(p) => {
            let response = SensorProfile::load(p)
                .map_err(|e| Error::context(format!("loading profile {}", p.display()), e))?
                .response;
            EncodePlan::Profile(p.clone(), response)
        }
    })
}

/// A checked `--encode` ([`plan_encoding`]).
#[derive(Clone, Debug)]
pub enum EncodePlan {
    Field,
    Device,
    Profile(PathBuf, Response),
}

impl EncodePlan {
    /// The encoding on frames linearised by `lin` (chosen by `choice`), and its record.
    pub fn resolve(&self, lin: &Linearise, choice: &ResponseChoice) -> (Encode, FrameEncoding) {
        match self {
            EncodePlan::Field => (
                Encode::Field,
                FrameEncoding::new(
                    "linear^(1/2.2), the field's convention",
                    Response::Gamma {
                        gamma: 2.2, // FIELD_GAMMA, exactly as written in f64
                    },
                ),
            ),
            EncodePlan::Device => device_encoding(lin, choice),
            EncodePlan::Profile(p, response) => (
                Encode::Curve(response.clone()),
                FrameEncoding::new(
                    format!(
                        "re-encoded with the device response of profile {}",
                        p.display()
                    ),
                    response.clone(),
                ),
            ),
        }
    }
}

/// `--encode device`: the device's codes under one recorded curve. An estimated response has
/// a table per channel and a record holds one curve ([`table_response`], the channels' mean):
/// the device's codes would then linearise through the record to other values than the ground
/// truth's, channel by channel. So each channel's codes are mapped through its own table and
/// the recorded curve (code' = curve(table_c(code))), which the record inverts to exactly the
/// linear values the ground truth was merged from; where the channels' tables agree the codes
/// are unchanged.
fn device_encoding(lin: &Linearise, choice: &ResponseChoice) -> (Encode, FrameEncoding) {
    match lin {
        Linearise::Curve(r) => (
            Encode::Device,
            FrameEncoding::new(
                format!("the device's own codes; response: {}", choice.describe()),
                r.clone(),
            ),
        ),
        Linearise::Table(t) => {
            let r = table_response(t);
            (
                Encode::Curve(r.clone()),
                FrameEncoding::new(
                    format!(
                        "the device's codes, each channel mapped through its own table onto \
                         the channels' mean curve; response: {}",
                        choice.describe()
                    ),
                    r,
                ),
            )
        }
    }
}

/// A linearisation table (linear per 8-bit code and channel, non-decreasing, 1 at code 255)
/// as one response: code per linear value, 1024 + 1 samples, the mean of the channels'
/// inverses.
pub fn table_response(t: &[Vec<f64>; 3]) -> Response {
    let n = 1024;
    let inverse = |t: &[f64], x: f64| -> f64 {
        let top = t.len() - 1;
        let z = t.partition_point(|&v| v < x);
        if z == 0 {
            return 0.0;
        }
        if z > top {
            return 1.0;
        }
        let (a, b) = (t[z - 1], t[z]);
        let f = if b > a { (x - a) / (b - a) } else { 1.0 };
        ((z - 1) as f64 + f.clamp(0.0, 1.0)) / top as f64
    };
    Response::Lut {
        lut: (0..=n)
            .map(|i| {
                let x = i as f64 / n as f64;
                (t.iter().map(|c| inverse(c, x)).sum::<f64>() / 3.0).clamp(0.0, 1.0)
            })
            .collect(),
    }
}
