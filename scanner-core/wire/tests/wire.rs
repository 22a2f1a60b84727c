//! The wire format: exact round trips, compact points, a streaming decoder that takes any chunks,
//! resynchronises after garbage, rejects corrupted frames and never panics.

use proptest::prelude::*;
use scanner_wire::{
    CameraBlock, Decoder, EndReason, Header, MAX_ENCODED, MAX_MESSAGE, Message, Notice, NoticeKind,
    PREVIEW_MAX_PIXELS, PlaneBlock, PlaneMethod, Points, Preview, PreviewState, Status, WireError,
    decode, encode, points,
};

fn header() -> Header {
    Header {
        scan_id: 0xDEAD_BEEF,
        width: 1600,
        height: 1200,
        unit_um: 10,
        camera: CameraBlock {
            fx: 1400.0,
            fy: 1400.5,
            cx: 799.5,
            cy: 599.5,
            k1: -0.06,
            k2: 0.02,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        },
        board: [
            PlaneBlock {
                normal: [0.7, 0.0, -0.7],
                offset: 565.0,
            },
            PlaneBlock {
                normal: [-0.7, 0.0, -0.7],
                offset: 565.0,
            },
        ],
        colour: true,
        method: PlaneMethod::LeastSquares,
    }
}

/// A stripe over a sphere and a board: smooth, with a jump.
fn stripe(n: usize) -> Vec<[i32; 3]> {
    (0..n)
        .map(|i| {
            let x = -300.0 + 0.57 * i as f64;
            let z = if (200..600).contains(&i) {
                500.0
                    - (70.0f64.powi(2) - ((i as f64 - 400.0) * 0.35).powi(2))
                        .max(0.0)
                        .sqrt()
            } else {
                800.0 - 0.3 * x.abs()
            };
            let y = 10.0 + 0.02 * x;
            [x, y, z].map(|v| points::quantise(v as f32).unwrap())
        })
        .collect()
}

fn frame_bytes(msg: &Message) -> Vec<u8> {
    let mut scratch = vec![0u8; MAX_MESSAGE];
    let mut out = vec![0u8; MAX_ENCODED];
    let n = encode(msg, &mut scratch, &mut out).unwrap();
    out.truncate(n);
    out
}

fn decode_all(bytes: &[u8], chunk: usize) -> (Vec<String>, scanner_wire::DecodeStats) {
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let mut seen = Vec::new();
    for c in bytes.chunks(chunk.max(1)) {
        d.feed(c, |m| seen.push(format!("{m:?}")));
    }
    (seen, d.stats())
}

#[test]
fn every_message_round_trips_and_points_average_few_bytes() {
    let pts = stripe(1000);
    let mut xyz = vec![0u8; 15 * pts.len()];
    let n = points::encode(&pts, &mut xyz).unwrap();
    xyz.truncate(n);
    let rgb: Vec<u8> = (0..3 * pts.len()).map(|i| (i % 251) as u8).collect();
    let sigma: Vec<u8> = (0..pts.len()).map(|i| (i % 97) as u8 + 60).collect();
    let msgs = [
        Message::Header(header()),
        Message::Points(Points {
            scan_id: 1,
            frame: 42,
            time_us: 1_400_000,
            plane: [0.0, 0.8, 0.6, -90.0],
            count: pts.len() as u32,
            xyz: &xyz,
            rgb: &rgb,
            uncertainty: &sigma,
        }),
        Message::Status(Status {
            scan_id: 1,
            frames: 60,
            packets: 55,
            points: 60000,
            bytes: 123456,
            skipped: [1, 2, 0, 0, 0, 2],
            fps_milli: 29970,
            done: true,
            ended: EndReason::Completed,
        }),
    ];
    let mut stream = Vec::new();
    for m in &msgs {
        stream.extend(frame_bytes(m));
    }
    for chunk in [1, 2, 7, 64, 4096, stream.len()] {
        let (seen, stats) = decode_all(&stream, chunk);
        assert_eq!(
            seen,
            msgs.iter()
                .map(|m| format!("{:?}", Ok::<_, WireError>(*m)))
                .collect::<Vec<_>>()
        );
        assert_eq!(stats.frames, 3);
        assert_eq!(stats.rejected(), 0);
    }
    // The points themselves, exactly.
    let mut back = Vec::new();
    points::decode(&xyz, pts.len(), |p| back.push(p)).unwrap();
    assert_eq!(back, pts);
    let framed = frame_bytes(&msgs[1]).len() as f64 - rgb.len() as f64 - sigma.len() as f64;
    let per_point = framed / pts.len() as f64;
    println!(
        "xyz {} bytes for {} points; framed without colour and uncertainty {per_point:.2} B/point \
         (+1 B/point for the uncertainty)",
        xyz.len(),
        pts.len()
    );
    assert!(per_point < 4.0, "{per_point}");
}

#[test]
fn garbage_and_corruption_are_counted_and_the_stream_resynchronises() {
    let good = frame_bytes(&Message::Header(header()));
    let mut stream = vec![0x13, 0x37, 0xFF, 0x00, 0x55];
    stream.extend(&good);
    // A frame with one flipped bit: the CRC catches it.
    let mut bad = good.clone();
    bad[10] ^= 0x04;
    stream.extend(&bad);
    stream.extend(&good);
    let (seen, stats) = decode_all(&stream, 5);
    let ok = seen.iter().filter(|s| s.starts_with("Ok")).count();
    assert_eq!(ok, 2, "{seen:?}");
    assert!(stats.rejected() >= 2, "{stats:?}");
    assert!(stats.bad_crc >= 1 || stats.bad_cobs >= 1);
}

#[test]
fn another_version_is_refused_by_name() {
    let mut scratch = vec![0u8; 512];
    let mut out = vec![0u8; 600];
    // Re-frame a valid body with version 9.
    let body_len = {
        scratch[0] = 9;
        postcard::to_slice(&Message::Header(header()), &mut scratch[1..])
            .unwrap()
            .len()
            + 1
    };
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&scratch[..body_len]);
    scratch[body_len..body_len + 4].copy_from_slice(&crc.to_le_bytes());
    let n = cobs::encode(&scratch[..body_len + 4], &mut out);
    out[n] = 0;
    let (seen, stats) = decode_all(&out[..=n], 3);
    assert_eq!(stats.bad_version, 1);
    assert!(seen[0].contains("UnknownVersion(9)"));
    assert_eq!(
        WireError::UnknownVersion(9).to_string(),
        "unknown protocol version 9 (this build reads 1 and 2)"
    );
}

#[test]
fn an_oversize_frame_is_dropped_without_losing_the_next() {
    let good = frame_bytes(&Message::Header(header()));
    let mut stream = vec![0x42u8; 300];
    stream.push(0);
    stream.extend(&good);
    let mut d = Decoder::<128>::new();
    let mut seen = Vec::new();
    d.feed(&stream, |m| seen.push(m.is_ok()));
    assert_eq!(seen, vec![false, true]);
    assert_eq!(d.stats().oversize, 1);
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn points_round_trip_exactly(pts in proptest::collection::vec(any::<[i32; 3]>(), 0..300)) {
        let mut buf = vec![0u8; 15 * pts.len()];
        let n = points::encode(&pts, &mut buf).unwrap();
        let mut back = Vec::new();
        points::decode(&buf[..n], pts.len(), |p| back.push(p)).unwrap();
        prop_assert_eq!(back, pts);
    }

    #[test]
    fn the_decoder_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..2000), chunk in 1usize..64) {
        let mut d = Decoder::<512>::new();
        for c in bytes.chunks(chunk) {
            d.feed(c, |m| {
                if let Ok(Message::Points(p)) = m {
                    let _ = points::decode(p.xyz, p.count as usize, |_| {});
                }
            });
        }
        prop_assert_eq!(d.stats().bytes, bytes.len() as u64);
    }

    #[test]
    fn point_decoding_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200), count in 0usize..100) {
        let _ = points::decode(&bytes, count, |_| {});
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The golden frame of `docs/wire.md`: this header, byte for byte. A change of these bytes is a
/// change of the format (see the document's rule for `VERSION`).
#[test]
fn the_golden_header_frame_of_the_spec_is_what_the_encoder_writes() {
    let bytes = frame_bytes(&Message::Header(header()));
    let golden =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/wire.md"))
            .unwrap();
    let start = golden.find("<!-- golden:begin -->").expect("golden block") + 21;
    let end = golden.find("<!-- golden:end -->").expect("golden block");
    let want: String = golden[start..end]
        .lines()
        .filter(|l| !l.starts_with("```"))
        .collect::<Vec<_>>()
        .join(" ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    assert_eq!(
        hex(&bytes),
        want,
        "\nthe encoder now writes:\n{}",
        hex(&bytes)
    );
    let mut d = Decoder::<MAX_ENCODED>::new();
    let mut got = None;
    d.feed(&bytes, |m| got = Some(m.map(|m| format!("{m:?}"))));
    assert_eq!(
        got.unwrap().unwrap(),
        format!("{:?}", Message::Header(header()))
    );
}

/// The validated layer: enum fields take only their values, the camera block and the planes
/// become checked core types.
#[test]
fn wire_enums_and_blocks_are_checked_at_the_parse() {
    // The method byte of a header frame set to 7: the frame is refused, not misread.
    let mut scratch = vec![0u8; MAX_MESSAGE];
    let mut payload = vec![0u8; MAX_MESSAGE];
    let n = postcard::to_slice(&Message::Header(header()), &mut payload)
        .unwrap()
        .len();
    // The header ends with the colour flag and the method byte.
    payload[n - 1] = 7;
    let _ = &mut scratch;
    assert!(postcard::from_bytes::<Message>(&payload[..n]).is_err());
    assert_eq!(EndReason::try_from(2u8), Ok(EndReason::Stopped));
    assert!(EndReason::try_from(3u8).is_err());
}

/// A message's postcard bytes.
fn body_of(msg: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; 4096];
    let n = postcard::to_slice(msg, &mut buf).unwrap().len();
    buf.truncate(n);
    buf
}

/// A frame as a version-1 head wrote it: the version byte, `body` (postcard), the CRC, COBS and
/// both delimiters.
fn frame_v1(body: &[u8]) -> Vec<u8> {
    let mut raw = vec![1u8];
    raw.extend_from_slice(body);
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0u8; raw.len() + raw.len() / 254 + 3];
    let n = cobs::encode(&raw, &mut out[1..]);
    out.truncate(n + 2);
    out[0] = 0;
    out[n + 1] = 0;
    out
}

#[test]
fn version_1_frames_are_still_read_and_their_points_carry_no_uncertainty() {
    // The documented sizes of the largest frame.
    assert_eq!(scanner_wire::MAX_MESSAGE, 78_080);
    assert_eq!(scanner_wire::MAX_ENCODED, 78_390);
    let pts = stripe(50);
    let mut xyz = vec![0u8; 15 * pts.len()];
    let n = points::encode(&pts, &mut xyz).unwrap();
    let v2 = Message::Points(Points {
        scan_id: 7,
        frame: 3,
        time_us: 99,
        plane: [0.0, 0.8, 0.6, -90.0],
        count: pts.len() as u32,
        xyz: &xyz[..n],
        rgb: &[],
        uncertainty: &[],
    });
    // Version 1's Points is version 2's without the last field: the empty slice's length byte.
    let body = body_of(&v2);
    assert_eq!(body.last(), Some(&0));
    let mut stream = frame_v1(&body[..body.len() - 1]);
    stream.extend(frame_v1(&body_of(&Message::Header(header()))));
    let (seen, stats) = decode_all(&stream, 5);
    assert_eq!(stats.frames, 2, "{seen:?}");
    assert_eq!(seen[0], format!("{:?}", Ok::<_, WireError>(v2)));
    assert_eq!(
        seen[1],
        format!("{:?}", Ok::<_, WireError>(Message::Header(header())))
    );
    // A version-1 Points frame that already carries the new field is not version 1's: refused.
    let (_, stats) = decode_all(&frame_v1(&body), 5);
    assert_eq!((stats.frames, stats.bad_payload), (0, 1));
    // And an uncertainty of the wrong length is refused as inconsistent points.
    let wrong = Message::Points(Points {
        uncertainty: &[5, 6],
        ..match v2 {
            Message::Points(p) => p,
            _ => unreachable!(),
        }
    });
    let (_, stats) = decode_all(&frame_bytes(&wrong), 7);
    assert_eq!((stats.frames, stats.bad_payload), (0, 1));
}

#[test]
fn the_uncertainty_code_spans_a_micrometre_to_63_mm_in_steps_of_4_percent() {
    use points::{uncertainty_code, uncertainty_mm};
    assert_eq!(uncertainty_code(0.001), 0);
    assert_eq!(uncertainty_code(0.0001), 0, "below the range: clamped");
    assert_eq!(uncertainty_code(1e6), 255, "above the range: clamped");
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert_eq!(uncertainty_code(bad), 255, "{bad}: unknown, the largest");
    }
    for c in 0..=255u8 {
        assert_eq!(uncertainty_code(uncertainty_mm(c)), c);
    }
    // within half a step (2.2 %) over the range
    for k in 0..400 {
        let mm = 0.0011 * 1.03f32.powi(k);
        if mm > 60.0 {
            break;
        }
        let back = uncertainty_mm(uncertainty_code(mm));
        assert!((back / mm - 1.0).abs() <= 0.022, "{mm} → {back}");
    }
}

/// The largest preview the limits allow.
fn preview<'a>(pixels: &'a [u8], markers: &'a [u8], stripe: &'a [u8]) -> Preview<'a> {
    Preview {
        scan_id: 9,
        frame: 30,
        width: 160,
        height: 120,
        scale: 8,
        pixels,
        markers,
        axis: 0,
        stripe,
        clipped_permille: 12,
        laser_dn: 66,
        state: PreviewState::Skipped,
        skip: 1,
        points: 0,
    }
}

/// Notices and previews round-trip; a preview that breaks its limits (pixels not its size, an
/// odd marker list, a stripe of another length, a skip reason out of range) or a notice of an
/// unknown kind is dropped as a bad payload, not misread.
#[test]
fn notices_and_previews_round_trip_and_bad_ones_are_refused() {
    let pixels: Vec<u8> = (0..PREVIEW_MAX_PIXELS).map(|i| (i % 256) as u8).collect();
    let markers: Vec<u8> = (0..512).map(|i| (i % 160) as u8).collect();
    let stripe: Vec<u8> = (0..160)
        .map(|i| if i % 7 == 0 { 255 } else { 60 })
        .collect();
    let good = [
        Message::Notice(Notice {
            scan_id: 9,
            kind: NoticeKind::SwitchLaserOn,
            seconds: 60,
        }),
        Message::Preview(preview(&pixels, &markers, &stripe)),
    ];
    for m in &good {
        let mut bytes = frame_bytes(m);
        assert!(bytes.len() <= MAX_ENCODED);
        let n = bytes.len();
        assert_eq!(decode(&mut bytes[1..n - 1]), Ok(*m));
    }
    let short = &pixels[..pixels.len() - 1];
    let odd = &markers[..3];
    let long = &stripe[..100];
    let bad = [
        preview(short, &markers, &stripe),
        preview(&pixels, odd, &stripe),
        preview(&pixels, &markers, long),
        Preview {
            skip: 6,
            ..preview(&pixels, &markers, &stripe)
        },
        Preview {
            width: 161,
            ..preview(&pixels, &markers, &stripe)
        },
    ];
    for p in bad {
        assert!(!p.is_consistent());
        let mut bytes = frame_bytes(&Message::Preview(p));
        let n = bytes.len();
        assert_eq!(decode(&mut bytes[1..n - 1]), Err(WireError::BadPayload));
    }
    // A notice's kind byte set to 9: refused.
    let mut body = body_of(&good[0]);
    let at = body.len() - 2;
    assert_eq!(body[at], NoticeKind::SwitchLaserOn as u8);
    body[at] = 9;
    assert!(postcard::from_bytes::<Message>(&body).is_err());
    assert_eq!(NoticeKind::try_from(3u8), Ok(NoticeKind::NoLaser));
    assert_eq!(NoticeKind::try_from(4u8), Ok(NoticeKind::LaserOffUnheard));
}
