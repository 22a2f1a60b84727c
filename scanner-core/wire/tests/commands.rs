//! Commands (host → head): exact round trips, a golden frame, and every way a frame can fail to
//! be a command told apart, so that the head can say why it refuses one.

use proptest::prelude::*;
use scanner_wire::command::{COMMANDS, MAX_CONTROL_VALUE, PREVIEW_MAX_EVERY};
use scanner_wire::{
    Command, CommandDecoder, CommandError, CommandFrame, CommandFrameError, HeadState,
    MAX_COMMAND_ENCODED, Message, Outcome, PreviewRequest, Reply, SweepRequest, VERSION, WireError,
    encode, encode_command,
};

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

fn frame(cmd: Command, seq: u32) -> Vec<u8> {
    let mut out = [0u8; MAX_COMMAND_ENCODED];
    let n = encode_command(&CommandFrame { seq, command: cmd }, &mut out).unwrap();
    out[..n].to_vec()
}

/// A frame around any body (version byte given), as a buggy or newer host would send it.
fn raw_frame(version: u8, body: &[u8]) -> Vec<u8> {
    let mut raw = vec![version];
    raw.extend_from_slice(body);
    let crc = CRC.checksum(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0u8; cobs::max_encoding_length(raw.len()) + 2];
    let n = cobs::encode(&raw, &mut out[1..]);
    out.truncate(n + 2);
    out
}

fn decode_all(bytes: &[u8]) -> Vec<Result<CommandFrame, CommandFrameError>> {
    let mut d = CommandDecoder::new();
    let mut got = Vec::new();
    d.feed(bytes, |r| got.push(r));
    got
}

fn every_command() -> Vec<Command> {
    vec![
        Command::Hello,
        Command::Preview(PreviewRequest {
            on: true,
            every: 30,
            scale: 4,
            picture: false,
            zoom: [0; 4],
        }),
        Command::Shot { board: true },
        Command::Calibrate,
        Command::Sweep(SweepRequest {
            disc: 1,
            axis: 2,
            colour: true,
            keep_board: false,
            frames: 120,
        }),
        Command::Stop,
        Command::Camera {
            control: 0,
            value: 250,
        },
        Command::Laser { on: false },
        Command::Turn { steps: -400 },
    ]
}

#[test]
fn every_command_goes_through_and_back_within_its_limit() {
    let cmds = every_command();
    assert_eq!(cmds.len() as u32, COMMANDS);
    for (i, c) in cmds.into_iter().enumerate() {
        let seq = u32::MAX - i as u32;
        let bytes = frame(c, seq);
        assert!(bytes.len() <= MAX_COMMAND_ENCODED);
        assert_eq!(
            decode_all(&bytes),
            vec![Ok(CommandFrame { seq, command: c })]
        );
        assert_eq!(c.check(), Ok(()), "{c:?}");
    }
}

/// The golden command of docs/wire.md: a sweep on the A4 disc, command 7.
#[test]
fn the_golden_command_frame_of_the_spec_is_what_the_encoder_writes() {
    let bytes = frame(
        Command::Sweep(SweepRequest {
            disc: 1,
            axis: 0,
            colour: false,
            keep_board: false,
            frames: 0,
        }),
        7,
    );
    let hex: Vec<String> = bytes.iter().map(|b| format!("{b:02x}")).collect();
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/wire.md"))
        .unwrap();
    let start = doc.find("<!-- golden-command:begin -->").expect("block") + 29;
    let end = doc.find("<!-- golden-command:end -->").expect("block");
    let want: Vec<&str> = doc[start..end]
        .lines()
        .filter(|l| !l.starts_with("```"))
        .flat_map(str::split_whitespace)
        .collect();
    assert_eq!(hex, want, "\nthe encoder now writes: {}", hex.join(" "));
}

#[test]
fn a_command_this_version_does_not_know_is_told_apart_with_its_number() {
    // seq 42 (varint 2a), variant 9 and beyond: a newer host's command
    for v in [9u8, 77] {
        let got = decode_all(&raw_frame(VERSION, &[0x2a, v]));
        assert_eq!(
            got,
            vec![Err(CommandFrameError::Command(CommandError::Unknown(
                42,
                u32::from(v)
            )))]
        );
    }
    // a known command cut short: malformed, its number kept
    let got = decode_all(&raw_frame(VERSION, &[0x2a, 4, 1]));
    assert_eq!(
        got,
        vec![Err(CommandFrameError::Command(CommandError::Malformed(42)))]
    );
    // a bool that is 2
    let got = decode_all(&raw_frame(VERSION, &[0x05, 7, 2]));
    assert_eq!(
        got,
        vec![Err(CommandFrameError::Command(CommandError::Malformed(5)))]
    );
    // trailing bytes after a whole command
    let got = decode_all(&raw_frame(VERSION, &[0x05, 0, 0]));
    assert_eq!(
        got,
        vec![Err(CommandFrameError::Command(CommandError::Malformed(5)))]
    );
    // not even a number: a varint that never ends
    let got = decode_all(&raw_frame(VERSION, &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff]));
    assert_eq!(
        got,
        vec![Err(CommandFrameError::Command(CommandError::Unreadable))]
    );
    // another version
    let got = decode_all(&raw_frame(9, &[0x05, 0]));
    assert_eq!(
        got,
        vec![Err(CommandFrameError::Frame(WireError::UnknownVersion(9)))]
    );
}

#[test]
fn an_oversized_frame_is_refused_unread_and_the_next_one_is_read() {
    let mut bytes = vec![0u8];
    bytes.extend(std::iter::repeat_n(0x55u8, 10 * MAX_COMMAND_ENCODED));
    bytes.extend(frame(Command::Stop, 3));
    let got = decode_all(&bytes);
    assert_eq!(
        got,
        vec![
            Err(CommandFrameError::Frame(WireError::Oversize)),
            Ok(CommandFrame {
                seq: 3,
                command: Command::Stop
            })
        ]
    );
}

#[test]
fn fields_out_of_range_are_named_with_their_limit() {
    let bad = [
        (
            Command::Preview(PreviewRequest {
                on: true,
                every: 0,
                scale: 0,
                picture: false,
                zoom: [0; 4],
            }),
            (2, i32::from(PREVIEW_MAX_EVERY)),
        ),
        (
            Command::Preview(PreviewRequest {
                on: true,
                every: 1,
                scale: 65,
                picture: false,
                zoom: [0; 4],
            }),
            (3, 64),
        ),
        (
            Command::Sweep(SweepRequest {
                disc: 3,
                axis: 0,
                colour: false,
                keep_board: false,
                frames: 0,
            }),
            (1, 2),
        ),
        (
            Command::Sweep(SweepRequest {
                disc: 0,
                axis: 9,
                colour: false,
                keep_board: false,
                frames: 0,
            }),
            (2, 2),
        ),
        (
            Command::Camera {
                control: 4,
                value: 0,
            },
            (1, 3),
        ),
        (
            Command::Camera {
                control: 0,
                value: -1,
            },
            (2, MAX_CONTROL_VALUE),
        ),
        (Command::Turn { steps: 0 }, (1, 1_000_000)),
        (Command::Turn { steps: i32::MIN }, (1, 1_000_000)),
    ];
    for (c, want) in bad {
        assert_eq!(c.check(), Err(want), "{c:?}");
    }
    // the preview switched off needs no cadence
    let off = Command::Preview(PreviewRequest {
        on: false,
        every: 0,
        scale: 0,
        picture: false,
        zoom: [0; 4],
    });
    assert_eq!(off.check(), Ok(()));
}

#[test]
fn replies_travel_as_messages() {
    let r = Reply {
        seq: 9,
        outcome: Outcome::TooFewShots,
        state: HeadState::Previewing,
        field: 1,
        detail: 3,
    };
    let mut scratch = vec![0u8; 256];
    let mut out = vec![0u8; 300];
    let n = encode(&Message::Reply(r), &mut scratch, &mut out).unwrap();
    let mut d = scanner_wire::Decoder::<512>::new();
    let mut got = None;
    d.feed(&out[..n], |m| got = Some(format!("{:?}", m.unwrap())));
    assert_eq!(got.unwrap(), format!("{:?}", Message::Reply(r)));
    assert_eq!(Message::Reply(r).scan_id(), None);
}

proptest! {
    /// Any bytes in any chunks: no panic, every byte looked at, and a good frame after the
    /// garbage still read.
    #[test]
    fn any_bytes_then_a_good_command(garbage in proptest::collection::vec(any::<u8>(), 0..400), chunk in 1usize..50) {
        let mut d = CommandDecoder::new();
        let mut last = None;
        for c in garbage.chunks(chunk) {
            d.feed(c, |r| last = Some(r));
        }
        let good = frame(Command::Hello, 77);
        for c in good.chunks(chunk) {
            d.feed(c, |r| last = Some(r));
        }
        prop_assert_eq!(last, Some(Ok(CommandFrame { seq: 77, command: Command::Hello })));
    }
}
