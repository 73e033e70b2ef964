//! The SLCAN codec against arbitrary input: every frame survives format → parse, every byte
//! string parses to a line or an error without panicking, a valid line formats back to
//! itself (up to hex case), and the line reader gives the same lines however the stream is
//! cut into reads.

use controller::slcan::{format, parse, Error, Line, LineReader, SlFrame, BELL, CR, MAX_LINE};
use proptest::prelude::*;

fn frame() -> impl Strategy<Value = SlFrame> {
    (
        any::<bool>(),
        any::<bool>(),
        0u8..=8,
        any::<[u8; 8]>(),
        any::<u32>(),
    )
        .prop_map(|(extended, remote, dlc, mut data, id)| {
            let id = if extended {
                id & 0x1FFF_FFFF
            } else {
                id & 0x7FF
            };
            if remote {
                data = [0; 8];
            } else {
                for b in data.iter_mut().skip(usize::from(dlc)) {
                    *b = 0;
                }
            }
            SlFrame {
                id,
                extended,
                remote,
                dlc,
                data,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn frames_round_trip(f in frame(), stamp in proptest::option::of(any::<u16>())) {
        let line = Line::Frame(f, stamp);
        let bytes = format(&line);
        let b = bytes.as_bytes();
        prop_assert_eq!(b.last(), Some(&CR));
        prop_assert!(b.len() <= MAX_LINE + 1);
        prop_assert_eq!(parse(&b[..b.len() - 1]), Ok(line));
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_valid_lines_reformat(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
        if let Ok(line) = parse(&bytes) {
            let out = format(&line);
            let mut want = bytes.to_ascii_uppercase();
            match line {
                Line::Error => {}
                _ => want.push(CR),
            }
            // commands and acks are case-sensitive (t ≠ T); only hex digits are folded
            let got = out.as_bytes();
            prop_assert_eq!(got.len(), want.len());
            prop_assert_eq!(got[1..].to_ascii_uppercase(), want[1..].to_vec());
            prop_assert_eq!(got.first(), bytes.first().or(Some(&CR)));
        }
    }

    #[test]
    fn near_miss_lines_are_errors(f in frame(), cut in 1usize..30, junk in any::<u8>()) {
        let line = format(&Line::Frame(f, None));
        let b = &line.as_bytes()[..line.as_bytes().len() - 1];
        // one byte short, or one byte too many (unless that makes a timestamp)
        if cut < b.len() {
            let short = &b[..b.len() - cut];
            let r = parse(short);
            prop_assert!(r.is_err() || cut >= b.len() - 1, "{:?} parsed from {:?}", r, short);
        }
        let mut long = b.to_vec();
        long.push(junk);
        prop_assert!(parse(&long).is_err());
    }

    #[test]
    fn reader_is_independent_of_how_the_stream_is_cut(
        lines in proptest::collection::vec((frame(), any::<bool>()), 1..12),
        noise in proptest::collection::vec(any::<u8>(), 0..60),
    ) {
        let mut stream = Vec::new();
        for (f, ack) in &lines {
            stream.extend_from_slice(format(&Line::Frame(*f, None)).as_bytes());
            if *ack {
                stream.extend_from_slice(format(&Line::Queued { extended: f.extended }).as_bytes());
            }
        }
        // a garbage line, then a frame: the reader must report one error at most and resync
        let mut garbage: Vec<u8> = noise.iter().copied().filter(|b| *b != CR && *b != b'\n' && *b != BELL).collect();
        garbage.push(CR);
        stream.extend_from_slice(&garbage);
        stream.extend_from_slice(format(&Line::Open).as_bytes());

        let mut r = LineReader::new();
        let got: Vec<Result<Line, Error>> = stream.iter().filter_map(|b| r.push(*b)).collect();
        let want_frames: Vec<Line> = lines
            .iter()
            .flat_map(|(f, ack)| {
                let mut v = vec![Line::Frame(*f, None)];
                if *ack {
                    v.push(Line::Queued { extended: f.extended });
                }
                v
            })
            .collect();
        prop_assert_eq!(got.len(), want_frames.len() + 2);
        for (g, w) in got.iter().zip(&want_frames) {
            prop_assert_eq!(g, &Ok(*w));
        }
        prop_assert_eq!(got.last(), Some(&Ok(Line::Open)));
        prop_assert_eq!(r.pending(), 0);
    }

    #[test]
    fn embedded_can_conversion_round_trips(f in frame()) {
        let raw: controller::proto::RawFrame = f.to_frame().unwrap();
        prop_assert_eq!(SlFrame::from_frame(&raw), Some(f));
    }
}
