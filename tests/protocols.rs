//! Literal-byte, error and property tests for every codec in `rigcal_devices::protocols`.

use proptest::prelude::*;
use rand::{RngExt, SeedableRng};

use rigcal_devices::protocols::can::{CanFrame, CanFrameError, CanId};
use rigcal_devices::protocols::canopen::{
    next_controlword_towards_enabled, od, CanOpenError, CanOpenMessage, Controlword, DriveState,
    EmcyErrorCode, Emergency, Heartbeat, Nmt, NmtCommand, NmtState, NodeId, PdoDirection,
    SdoAbortCode, SdoData, SdoRequest, SdoResponse, Statusword, TouchProbeFunction,
    TouchProbeStatus,
};
use rigcal_devices::protocols::movemaster::{
    quantise_increment, quantise_joint_move, Acceleration, Command, Decimal, ErrorStatus,
    JointNumber, LineFramer, MovemasterError, Resolution, SpeedLevel, WhereReply,
};
use rigcal_devices::protocols::penmount::{
    checksum, Axis, PenMountDecoder, PenMountError, PenMountPacket,
};
use rigcal_devices::protocols::slcan::{Bitrate, SlcanDecoder, SlcanError, SlcanMessage};

fn node(n: u8) -> NodeId {
    NodeId::new(n).unwrap()
}

fn dec(v: f64) -> Decimal {
    Decimal::from_f64(v, Resolution::default()).unwrap()
}

// ============================================================== CAN

#[test]
fn can_frame_validation() {
    assert_eq!(
        CanFrame::new_standard(0x800, &[]),
        Err(CanFrameError::IdTooLarge {
            id: 0x800,
            bits: 11,
            max: 0x7FF
        })
    );
    assert_eq!(
        CanFrame::new_extended(0x2000_0000, &[]),
        Err(CanFrameError::IdTooLarge {
            id: 0x2000_0000,
            bits: 29,
            max: 0x1FFF_FFFF
        })
    );
    assert_eq!(
        CanFrame::new_standard(0x123, &[0; 9]),
        Err(CanFrameError::TooManyBytes { len: 9 })
    );
    assert_eq!(
        CanFrame::new(CanId::Standard(0xFFFF), &[]),
        Err(CanFrameError::IdTooLarge {
            id: 0xFFFF,
            bits: 11,
            max: 0x7FF
        })
    );
    assert_eq!(
        CanFrame::new_remote(CanId::Standard(1), 9),
        Err(CanFrameError::DlcTooLarge { dlc: 9 })
    );
    let f = CanFrame::new_standard(0x7FF, &[1, 2, 3]).unwrap();
    assert_eq!(f.raw_id(), 0x7FF);
    assert_eq!(f.data(), &[1, 2, 3]);
    assert_eq!(f.dlc(), 3);
    assert!(!f.is_extended() && !f.is_remote());
    let r = CanFrame::new_remote(CanId::Extended(0x1FFF_FFFF), 4).unwrap();
    assert!(r.is_remote() && r.is_extended());
    assert_eq!(r.dlc(), 4);
    assert!(r.data().is_empty());
}

// ============================================================== Movemaster

#[test]
fn movemaster_encode_literal() {
    let mj = Command::MoveJoints([dec(10.0), dec(-5.5), dec(0.0), dec(0.0), dec(0.0)]);
    assert_eq!(mj.encode(), b"MJ +10.0,-5.5,+0.0,+0.0,+0.0\r");
    assert_eq!(Command::Nest.encode(), b"NT\r");
    assert_eq!(Command::Where.encode(), b"WH\r");
    assert_eq!(Command::ErrorRead.encode(), b"ER\r");
    assert_eq!(Command::Reset.encode(), b"RS\r");
    let sp = |l, a| Command::Speed {
        level: SpeedLevel::new(l).unwrap(),
        accel: a,
    };
    assert_eq!(sp(5, None).encode(), b"SP 5\r");
    assert_eq!(sp(9, Some(Acceleration::High)).encode(), b"SP 9,H\r");
    assert_eq!(sp(0, Some(Acceleration::Low)).encode(), b"SP 0,L\r");
    let dj = Command::MoveJoint {
        joint: JointNumber::new(2).unwrap(),
        angle: dec(-0.5),
    };
    assert_eq!(dj.encode(), b"DJ 2,-0.5\r");
    // Resolution of 2 decimals and 0 decimals.
    let r2 = Resolution::new(2).unwrap();
    let mj2 = Command::MoveJoints([
        Decimal::from_f64(1.25, r2).unwrap(),
        Decimal::from_f64(-0.05, r2).unwrap(),
        Decimal::zero(r2),
        Decimal::new(7, 0).unwrap(),
        Decimal::new(-123, 0).unwrap(),
    ]);
    assert_eq!(mj2.encode(), b"MJ +1.25,-0.05,+0.00,+7,-123\r");
}

#[test]
fn movemaster_mp_literal_bytes_and_decoding() {
    let mp = Command::move_pose(&[250.04, -0.05, 400.0, -89.96, 12.349]).unwrap();
    assert_eq!(mp.encode(), b"MP +250.0,-0.1,+400.0,-90.0,+12.3\r");
    assert_eq!(
        Command::decode(b"MP +250.0,-0.1,+400.0,-90.0,+12.3\r").unwrap(),
        mp
    );
    assert_eq!(Command::decode(b"MP250,-.1,400,-90.0,12.30").unwrap(), mp);
    assert!(matches!(
        Command::decode(b"MP 1,2,3,4\r"),
        Err(MovemasterError::WrongFieldCount {
            what: "MP",
            expected: 5,
            found: 4
        })
    ));
    assert!(matches!(
        Command::decode(b"MP 1,2,x,4,5\r"),
        Err(MovemasterError::BadNumber {
            what: "MP",
            field: 2,
            ..
        })
    ));
    assert!(matches!(
        Command::move_pose(&[f64::NAN, 0.0, 0.0, 0.0, 0.0]),
        Err(MovemasterError::NotFinite { .. })
    ));
}

#[test]
fn movemaster_decode_accepts_manual_forms() {
    let expected = Command::MoveJoints([dec(10.0), dec(-5.5), dec(0.0), dec(0.0), dec(0.0)]);
    for line in [
        &b"MJ +10.0,-5.5,+0.0,+0.0,+0.0\r"[..],
        b"MJ 10,-5.5,0,0,0",
        b"MJ10.00,-5.50,-0,+0.,.0\r\n",
        b"MJ  +10.0 , -5.5 ,0,0,0 \r",
    ] {
        assert_eq!(Command::decode(line), Ok(expected), "{line:?}");
    }
    assert_eq!(
        Command::decode(b"SP5"),
        Ok(Command::Speed {
            level: SpeedLevel::new(5).unwrap(),
            accel: None
        })
    );
    assert_eq!(
        Command::decode(b"SP 3,L\r"),
        Ok(Command::Speed {
            level: SpeedLevel::new(3).unwrap(),
            accel: Some(Acceleration::Low)
        })
    );
    assert_eq!(
        Command::decode(b"DJ 5,-.5\r"),
        Ok(Command::MoveJoint {
            joint: JointNumber::new(5).unwrap(),
            angle: dec(-0.5)
        })
    );
    assert_eq!(Command::decode(b"NT\r"), Ok(Command::Nest));
    assert_eq!(Command::decode(b"RS"), Ok(Command::Reset));
}

#[test]
fn movemaster_decode_rejects_with_specific_errors() {
    assert_eq!(Command::decode(b"\r"), Err(MovemasterError::Empty));
    assert_eq!(
        Command::decode(b"MJ 1,2,3,4\r"),
        Err(MovemasterError::WrongFieldCount {
            what: "MJ",
            expected: 5,
            found: 4
        })
    );
    assert!(matches!(
        Command::decode(b"MJ 1,2,x,4,5\r"),
        Err(MovemasterError::BadNumber { field: 2, .. })
    ));
    assert!(matches!(
        Command::decode(b"MJ 1,2,3,4,--5\r"),
        Err(MovemasterError::BadNumber { field: 4, .. })
    ));
    assert!(matches!(
        Command::decode(b"MJ 1.23456,0,0,0,0\r"),
        Err(MovemasterError::TooManyDecimals { max: 4, .. })
    ));
    assert!(matches!(
        Command::decode(b"SP 10\r"),
        Err(MovemasterError::OutOfRange { what: "speed", .. })
    ));
    assert!(matches!(
        Command::decode(b"SP 5,X\r"),
        Err(MovemasterError::OutOfRange {
            what: "SP acceleration",
            ..
        })
    ));
    assert!(matches!(
        Command::decode(b"DJ 6,1.0\r"),
        Err(MovemasterError::OutOfRange {
            what: "joint number",
            ..
        })
    ));
    assert!(matches!(
        Command::decode(b"NT 1\r"),
        Err(MovemasterError::WrongFieldCount { what: "NT", .. })
    ));
    assert_eq!(
        Command::decode(b"MO 3\r"),
        Err(MovemasterError::UnknownCommand {
            mnemonic: "MO".into()
        })
    );
    assert_eq!(
        Command::decode(b"W\xffH\r"),
        Err(MovemasterError::NotAscii {
            byte: 0xFF,
            offset: 1
        })
    );
}

#[test]
fn movemaster_replies_literal() {
    let wh = WhereReply {
        x: 250.0,
        y: 0.0,
        z: 400.0,
        pitch: -90.0,
        roll: 0.0,
    };
    assert_eq!(wh.encode(), b"+250.0,+0.0,+400.0,-90.0,+0.0\r");
    assert_eq!(
        WhereReply::decode(b"+250.0,+0.0,+400.0,-90.0,+0.0\r"),
        Ok(wh)
    );
    assert_eq!(WhereReply::decode(b"250,0,400,-90,0\r\n"), Ok(wh));
    assert_eq!(
        WhereReply::decode_body(b"+250.0,+0.0,+400.0,-90.0,+0.0"),
        Ok(wh)
    );
    assert_eq!(
        WhereReply::decode(b"+250.0,+0.0,+400.0,-90.0,+0.0"),
        Err(MovemasterError::MissingTerminator)
    );
    assert_eq!(
        WhereReply::decode(b"+250.0,+0.0,+400.0,-90.0\r"),
        Err(MovemasterError::WrongFieldCount {
            what: "WH reply",
            expected: 5,
            found: 4
        })
    );
    assert!(matches!(
        WhereReply::decode(b"+250.0,+0.0,abc,-90.0,+0.0\r"),
        Err(MovemasterError::BadNumber { field: 2, .. })
    ));
    assert_eq!(WhereReply::decode(b"\r"), Err(MovemasterError::Empty));

    assert_eq!(ErrorStatus::None.encode(), b"0\r");
    assert_eq!(ErrorStatus::Hardware.encode(), b"1\r");
    assert_eq!(ErrorStatus::Position.encode(), b"2\r");
    assert_eq!(ErrorStatus::decode(b"0\r"), Ok(ErrorStatus::None));
    assert_eq!(ErrorStatus::decode(b"1\r"), Ok(ErrorStatus::Hardware));
    assert_eq!(ErrorStatus::decode(b"2\r\n"), Ok(ErrorStatus::Position));
    assert!(matches!(
        ErrorStatus::decode(b"3\r"),
        Err(MovemasterError::OutOfRange {
            what: "error code",
            ..
        })
    ));
    assert_eq!(
        ErrorStatus::decode(b"0"),
        Err(MovemasterError::MissingTerminator)
    );
    assert!(matches!(
        ErrorStatus::decode(b"x\r"),
        Err(MovemasterError::BadNumber { .. })
    ));
    assert!(matches!(
        ErrorStatus::decode(b"0,1\r"),
        Err(MovemasterError::WrongFieldCount { .. })
    ));
}

#[test]
fn quantise_rounds_absolute_targets_not_increments() {
    let res = Resolution::default();
    // Two moves of +0.14°: independent rounding would send +0.1 twice (0.2 total);
    // rounding the absolute target sends +0.1 then +0.2 (0.3 = round(0.28)).
    let s1 = quantise_increment(0.14, 0, res).unwrap();
    assert_eq!((s1.increment_counts, s1.commanded_counts), (1, 1));
    let s2 = quantise_increment(0.28, s1.commanded_counts, res).unwrap();
    assert_eq!((s2.increment_counts, s2.commanded_counts), (2, 3));
    assert_eq!(s2.increment, dec(0.2));
    assert!(matches!(
        quantise_increment(f64::NAN, 0, res),
        Err(MovemasterError::NotFinite { .. })
    ));
    let (cmd, counts) =
        quantise_joint_move(&[1.06, -2.0, 0.0, 0.04, 0.05], &[0, 0, 0, 0, 0], res).unwrap();
    assert_eq!(cmd.encode(), b"MJ +1.1,-2.0,+0.0,+0.0,+0.1\r");
    assert_eq!(counts, [11, -20, 0, 0, 1]);
}

#[test]
fn quantise_never_accumulates_over_1000_random_moves() {
    for decimals in 0..=3 {
        let res = Resolution::new(decimals).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(0x5EED + u64::from(decimals));
        let mut commanded: i64 = 0;
        let mut sum_increments: i64 = 0;
        let mut target = 0.0f64;
        for _ in 0..1000 {
            target += rng.random_range(-7.3..7.3);
            let step = quantise_increment(target, commanded, res).unwrap();
            // The wire value is exactly the integer increment.
            assert_eq!(step.increment.to_counts(res), Some(step.increment_counts));
            sum_increments += step.increment_counts;
            commanded = step.commanded_counts;
            assert_eq!(sum_increments, res.to_counts(target).unwrap());
        }
        assert_eq!(sum_increments, res.to_counts(target).unwrap());
    }
}

#[test]
fn line_framer_literal() {
    let mut f = LineFramer::new(8);
    assert_eq!(f.push(b"WH\r+1"), vec![Ok(b"WH".to_vec())]);
    assert_eq!(f.pending(), 2);
    assert_eq!(
        f.push(b".0\r\n0\r"),
        vec![Ok(b"+1.0".to_vec()), Ok(b"0".to_vec())]
    );
    // Overflow: one error, discard to the next CR, then resync.
    let out = f.push(b"ABCDEFGHIJK\rNT\r");
    assert_eq!(
        out,
        vec![
            Err(MovemasterError::LineTooLong { max: 8 }),
            Ok(b"NT".to_vec())
        ]
    );
    assert_eq!(f.discarded_bytes(), 11);
}

// ============================================================== CANopen

#[test]
fn sdo_client_literal_bytes() {
    let up = SdoRequest::Upload {
        index: od::STATUSWORD,
        sub: 0,
    }
    .encode(node(2));
    assert_eq!(up.raw_id(), 0x602);
    assert_eq!(up.data(), &[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]);

    let cw = SdoRequest::Download {
        index: od::CONTROLWORD,
        sub: 0,
        data: SdoData::from_u16(Controlword::ENABLE_OPERATION.0),
    }
    .encode(node(3));
    assert_eq!(cw.raw_id(), 0x603);
    assert_eq!(cw.data(), &[0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0, 0]);

    let tp = SdoRequest::Download {
        index: od::TARGET_POSITION,
        sub: 0,
        data: SdoData::from_i32(-1000),
    };
    assert_eq!(
        tp.encode_payload(),
        [0x23, 0x7A, 0x60, 0x00, 0x18, 0xFC, 0xFF, 0xFF]
    );
    let mode = SdoRequest::Download {
        index: od::MODES_OF_OPERATION,
        sub: 0,
        data: SdoData::from_i8(od::MODE_PROFILE_POSITION),
    };
    assert_eq!(
        mode.encode_payload(),
        [0x2F, 0x60, 0x60, 0x00, 0x01, 0, 0, 0]
    );
    let three = SdoRequest::Download {
        index: 0x2000,
        sub: 5,
        data: SdoData::new(&[1, 2, 3]).unwrap(),
    };
    assert_eq!(three.encode_payload(), [0x27, 0x00, 0x20, 0x05, 1, 2, 3, 0]);
    let abort = SdoRequest::Abort {
        index: 0x1017,
        sub: 0,
        code: SdoAbortCode::Timeout,
    };
    assert_eq!(
        abort.encode_payload(),
        [0x80, 0x17, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05]
    );
    // Server side decodes them back.
    assert_eq!(
        SdoRequest::decode(&cw),
        Ok((
            node(3),
            SdoRequest::Download {
                index: 0x6040,
                sub: 0,
                data: SdoData::from_u16(0x000F)
            }
        ))
    );
    assert_eq!(
        SdoRequest::decode(&up),
        Ok((
            node(2),
            SdoRequest::Upload {
                index: 0x6041,
                sub: 0
            }
        ))
    );
}

#[test]
fn sdo_server_literal_bytes() {
    let frame = CanFrame::new_standard(0x582, &[0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0]).unwrap();
    let (n, resp) = SdoResponse::decode(&frame).unwrap();
    assert_eq!(n, node(2));
    match resp {
        SdoResponse::UploadData { index, sub, data } => {
            assert_eq!((index, sub), (0x6041, 0));
            assert_eq!(data.len(), 2);
            assert_eq!(data.to_u32(), 0x0237);
        }
        other => panic!("unexpected {other:?}"),
    }
    // Encode side of the emulator.
    let enc = SdoResponse::UploadData {
        index: 0x6041,
        sub: 0,
        data: SdoData::from_u16(0x0237),
    }
    .encode(node(2));
    assert_eq!(enc, frame);
    let lens = [(0x4F, 1), (0x4B, 2), (0x47, 3), (0x43, 4), (0x42, 4)];
    for (cmd, len) in lens {
        let r = SdoResponse::decode_payload(&[cmd, 0x64, 0x60, 0, 0xFF, 0xFF, 0xFF, 0xFF]).unwrap();
        let SdoResponse::UploadData { data, .. } = r else {
            panic!("{r:?}")
        };
        assert_eq!(data.len(), len, "cmd {cmd:#x}");
        assert_eq!(data.to_i32(), -1);
    }
    assert_eq!(
        SdoResponse::DownloadAck {
            index: 0x6040,
            sub: 0
        }
        .encode_payload(),
        [0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0]
    );
    let abort = SdoResponse::decode_payload(&[0x80, 0x7A, 0x60, 0x00, 0x00, 0x00, 0x02, 0x06]);
    assert_eq!(
        abort,
        Ok(SdoResponse::Abort {
            index: 0x607A,
            sub: 0,
            code: SdoAbortCode::ObjectDoesNotExist
        })
    );
    // Segmented / unsupported / malformed.
    assert_eq!(
        SdoResponse::decode_payload(&[0x41, 0x08, 0x10, 0, 20, 0, 0, 0]),
        Err(CanOpenError::SegmentedNotSupported {
            index: 0x1008,
            sub: 0
        })
    );
    assert_eq!(
        SdoRequest::decode_payload(&[0x21, 0x08, 0x10, 0, 20, 0, 0, 0]),
        Err(CanOpenError::SegmentedNotSupported {
            index: 0x1008,
            sub: 0
        })
    );
    assert_eq!(
        SdoRequest::decode_payload(&[0x00, 0, 0, 0, 0, 0, 0, 0]),
        Err(CanOpenError::UnsupportedCommandSpecifier { command: 0x00 })
    );
    assert_eq!(
        SdoRequest::decode_payload(&[0xA0, 0, 0, 0, 0, 0, 0, 0]),
        Err(CanOpenError::UnsupportedCommandSpecifier { command: 0xA0 })
    );
    assert_eq!(
        SdoResponse::decode_payload(&[0x60, 0x40, 0x60, 0, 0, 0, 0]),
        Err(CanOpenError::WrongLength {
            what: "SDO response",
            expected: "8",
            found: 7
        })
    );
    let wrong_dir = CanFrame::new_standard(0x602, &[0x60, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    assert!(matches!(
        SdoResponse::decode(&wrong_dir),
        Err(CanOpenError::WrongCobId { cob_id: 0x602, .. })
    ));
}

#[test]
fn sdo_abort_codes_table() {
    let table = [
        (0x0504_0000, SdoAbortCode::Timeout),
        (0x0601_0000, SdoAbortCode::UnsupportedAccess),
        (0x0601_0001, SdoAbortCode::WriteOnly),
        (0x0601_0002, SdoAbortCode::ReadOnly),
        (0x0602_0000, SdoAbortCode::ObjectDoesNotExist),
        (0x0604_0041, SdoAbortCode::CannotBeMapped),
        (0x0607_0010, SdoAbortCode::LengthMismatch),
        (0x0609_0011, SdoAbortCode::SubIndexDoesNotExist),
        (0x0609_0030, SdoAbortCode::ValueRangeExceeded),
        (0x0800_0000, SdoAbortCode::GeneralError),
        (0x0800_0020, SdoAbortCode::DataCannotBeStored),
        (0x0800_0021, SdoAbortCode::DataCannotBeStoredLocalControl),
        (0x0800_0022, SdoAbortCode::DataCannotBeStoredDeviceState),
        (0x1234_5678, SdoAbortCode::Other(0x1234_5678)),
    ];
    for (code, kind) in table {
        assert_eq!(SdoAbortCode::from_code(code), kind);
        assert_eq!(kind.code(), code);
    }
    assert_eq!(
        SdoAbortCode::ReadOnly.description(),
        "attempt to write a read-only object"
    );
}

#[test]
fn nmt_heartbeat_emcy_literal() {
    let start = Nmt {
        command: NmtCommand::Start,
        node: Some(node(2)),
    }
    .encode();
    assert_eq!((start.raw_id(), start.data()), (0x000, &[0x01, 0x02][..]));
    let reset_all = Nmt {
        command: NmtCommand::ResetCommunication,
        node: None,
    }
    .encode();
    assert_eq!(reset_all.data(), &[0x82, 0x00]);
    for (cmd, cs) in [
        (NmtCommand::Stop, 0x02),
        (NmtCommand::EnterPreOperational, 0x80),
        (NmtCommand::ResetNode, 0x81),
    ] {
        assert_eq!(cmd.code(), cs);
    }
    assert_eq!(Nmt::decode(&reset_all).unwrap().node, None);
    assert_eq!(
        Nmt::decode(&CanFrame::new_standard(0, &[0x03, 0x01]).unwrap()),
        Err(CanOpenError::UnknownNmtCommand { cs: 0x03 })
    );
    assert_eq!(
        Nmt::decode(&CanFrame::new_standard(0, &[0x01, 0x80]).unwrap()),
        Err(CanOpenError::InvalidNodeId { node: 0x80 })
    );

    let hb = Heartbeat {
        node: node(5),
        state: NmtState::Operational,
    }
    .encode();
    assert_eq!((hb.raw_id(), hb.data()), (0x705, &[0x05][..]));
    let boot = CanFrame::new_standard(0x77F, &[0x00]).unwrap();
    assert_eq!(
        Heartbeat::decode(&boot),
        Ok(Heartbeat {
            node: node(127),
            state: NmtState::BootUp
        })
    );
    assert_eq!(NmtState::Stopped.code(), 0x04);
    assert_eq!(NmtState::PreOperational.code(), 0x7F);
    assert_eq!(
        Heartbeat::decode(&CanFrame::new_standard(0x701, &[0x06]).unwrap()),
        Err(CanOpenError::UnknownNmtState { state: 0x06 })
    );

    let emcy = Emergency {
        node: node(1),
        error_code: EmcyErrorCode::FollowingError,
        error_register: 0x80,
        manufacturer: [1, 2, 3, 4, 5],
    };
    let f = emcy.encode();
    assert_eq!(f.raw_id(), 0x081);
    assert_eq!(f.data(), &[0x11, 0x86, 0x80, 1, 2, 3, 4, 5]);
    assert_eq!(Emergency::decode(&f), Ok(emcy));
    for (code, kind) in [
        (0x0000, EmcyErrorCode::NoError),
        (0x2310, EmcyErrorCode::OverCurrent),
        (0x7300, EmcyErrorCode::Sensor),
        (0x5530, EmcyErrorCode::DataStorage),
        (0x8611, EmcyErrorCode::FollowingError),
        (0xFF01, EmcyErrorCode::Other(0xFF01)),
    ] {
        assert_eq!(EmcyErrorCode::from_code(code), kind);
        assert_eq!(kind.code(), code);
    }
    assert!(matches!(
        Emergency::decode(&CanFrame::new_standard(0x081, &[0; 7]).unwrap()),
        Err(CanOpenError::WrongLength { found: 7, .. })
    ));
}

#[test]
fn canopen_classification() {
    let cls =
        |id: u16, data: &[u8]| CanOpenMessage::decode(&CanFrame::new_standard(id, data).unwrap());
    assert_eq!(cls(0x080, &[]), Ok(CanOpenMessage::Sync));
    assert!(matches!(cls(0x000, &[1, 0]), Ok(CanOpenMessage::Nmt(_))));
    assert!(matches!(
        cls(0x085, &[0; 8]),
        Ok(CanOpenMessage::Emergency(_))
    ));
    assert!(matches!(
        cls(0x702, &[0x7F]),
        Ok(CanOpenMessage::Heartbeat(_))
    ));
    assert!(matches!(
        cls(0x602, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]),
        Ok(CanOpenMessage::SdoRequest { .. })
    ));
    assert!(matches!(
        cls(0x582, &[0x60, 0x40, 0x60, 0, 0, 0, 0, 0]),
        Ok(CanOpenMessage::SdoResponse { .. })
    ));
    for (id, dir, num) in [
        (0x181, PdoDirection::Transmit, 1),
        (0x201, PdoDirection::Receive, 1),
        (0x282, PdoDirection::Transmit, 2),
        (0x302, PdoDirection::Receive, 2),
        (0x383, PdoDirection::Transmit, 3),
        (0x403, PdoDirection::Receive, 3),
        (0x484, PdoDirection::Transmit, 4),
        (0x504, PdoDirection::Receive, 4),
    ] {
        match cls(id, &[1, 2]) {
            Ok(CanOpenMessage::Pdo {
                direction, number, ..
            }) => assert_eq!((direction, number), (dir, num), "{id:#x}"),
            other => panic!("{id:#x}: {other:?}"),
        }
    }
    assert!(matches!(cls(0x100, &[0; 6]), Ok(CanOpenMessage::Other(_))));
    let ext = CanFrame::new_extended(0x602, &[0; 8]).unwrap();
    assert!(matches!(
        CanOpenMessage::decode(&ext),
        Ok(CanOpenMessage::Other(_))
    ));
    assert!(matches!(
        cls(0x080, &[1]),
        Err(CanOpenError::WrongLength { what: "SYNC", .. })
    ));
}

#[test]
fn cia402_statusword_states_and_bits() {
    let table = [
        (0x0000, DriveState::NotReadyToSwitchOn),
        (0x0040, DriveState::SwitchOnDisabled),
        (0x0250, DriveState::SwitchOnDisabled),
        (0x0231, DriveState::ReadyToSwitchOn),
        (0x0233, DriveState::SwitchedOn),
        (0x0237, DriveState::OperationEnabled),
        (0x1637, DriveState::OperationEnabled),
        (0x0217, DriveState::QuickStopActive),
        (0x021F, DriveState::FaultReactionActive),
        (0x0218, DriveState::Fault),
        (0x0008, DriveState::Fault),
    ];
    for (w, s) in table {
        assert_eq!(Statusword(w).state(), Ok(s), "{w:#06x}");
        assert_eq!(Statusword::for_state(s).state(), Ok(s));
    }
    assert_eq!(
        Statusword(0x0001).state(),
        Err(CanOpenError::UnknownDriveState { statusword: 0x0001 })
    );
    let sw = Statusword(0x36B7);
    assert!(sw.target_reached() && sw.setpoint_acknowledge() && sw.following_error());
    assert!(sw.warning() && sw.remote());
    let off = Statusword(0x0237);
    assert!(!off.target_reached() && !off.setpoint_acknowledge() && !off.following_error());
    assert!(!off.warning());
    assert!(Statusword(0x0400).target_reached());
    assert!(Statusword(0x1000).setpoint_acknowledge());
    assert!(Statusword(0x2000).following_error());
    assert!(Statusword(0x0080).warning());
}

/// The touch probe objects (CiA 402 / IEC 61800-7-201, as drive manuals print them: e.g. the
/// MOONS' EtherCAT drive manual §3.10, Beckhoff's AX8000 object pages 0x60B8–0x60BC).
#[test]
fn cia402_touch_probe_objects_and_bits() {
    assert_eq!(od::TOUCH_PROBE_FUNCTION, 0x60B8);
    assert_eq!(od::TOUCH_PROBE_STATUS, 0x60B9);
    assert_eq!(od::TOUCH_PROBE_1_POSITIVE, 0x60BA);
    assert_eq!(od::TOUCH_PROBE_1_NEGATIVE, 0x60BB);
    // Probe 1 enabled (bit 0), first event (bit 1 = 0), its own input (bits 2–3 = 00),
    // the positive edge sampled (bit 4).
    let armed = TouchProbeFunction::probe1_first_positive_edge();
    assert_eq!(armed.0, 0x0011);
    assert!(armed.probe1_enabled() && armed.probe1_positive_edge());
    assert!(!armed.probe1_continuous() && !armed.probe1_negative_edge());
    assert_eq!(armed.probe1_source(), 0);
    assert_eq!(TouchProbeFunction::OFF.0, 0);
    // Beckhoff's AX8000 default 0x3838 ("configure the source via 0x60D0"): both probes off,
    // source `10` (0x60D0) and both edges sampled, per probe.
    let beckhoff = TouchProbeFunction(0x3838);
    assert_eq!(beckhoff.probe1_source(), 0b10);
    assert!(beckhoff.probe1_positive_edge() && beckhoff.probe1_negative_edge());
    assert!(!beckhoff.probe1_enabled() && !beckhoff.probe1_continuous());
    assert!(TouchProbeFunction(0x0002).probe1_continuous());
    assert_eq!(TouchProbeFunction(0x0004).probe1_source(), 0b01); // the zero impulse
                                                                  // 0x60B9: bit 0 enabled, bit 1 positive edge stored, bit 2 negative edge stored; probe
                                                                  // 2's bits (8–10) are not probe 1's.
    assert_eq!(TouchProbeStatus::probe1(true, true).0, 0x0003);
    assert_eq!(TouchProbeStatus::probe1(true, false).0, 0x0001);
    assert_eq!(TouchProbeStatus::probe1(false, false).0, 0x0000);
    let st = TouchProbeStatus(0x0005);
    assert!(st.probe1_enabled() && st.probe1_negative_stored() && !st.probe1_positive_stored());
    let probe2 = TouchProbeStatus(0x0700);
    assert!(!probe2.probe1_enabled() && !probe2.probe1_positive_stored());
    assert!(!probe2.probe1_negative_stored());
    // On the wire: an expedited write of 0x0011 to 0x60B8 of node 3, byte for byte.
    let req = SdoRequest::Download {
        index: od::TOUCH_PROBE_FUNCTION,
        sub: 0,
        data: SdoData::from_u16(armed.0),
    };
    let f = req.encode(node(3));
    assert_eq!(f.id().raw(), 0x603);
    assert_eq!(f.data(), &[0x2B, 0xB8, 0x60, 0x00, 0x11, 0x00, 0x00, 0x00]);
}

#[test]
fn cia402_controlwords() {
    assert_eq!(Controlword::SHUTDOWN.0, 0x0006);
    assert_eq!(Controlword::SWITCH_ON.0, 0x0007);
    assert_eq!(Controlword::ENABLE_OPERATION.0, 0x000F);
    assert_eq!(Controlword::DISABLE_VOLTAGE.0, 0x0000);
    assert_eq!(Controlword::QUICK_STOP.0, 0x0002);
    assert_eq!(Controlword::FAULT_RESET.0, 0x0080);
    let abs = Controlword::ENABLE_OPERATION.with_new_setpoint(true);
    assert_eq!(abs.0, 0x001F);
    assert_eq!(abs.with_change_set_immediately(true).0, 0x003F);
    assert_eq!(abs.with_relative(true).0, 0x005F);
    assert_eq!(abs.with_relative(true).with_relative(false).0, 0x001F);
    assert_eq!(abs.with_new_setpoint(false).0, 0x000F);
    assert_eq!(Controlword::ENABLE_OPERATION.with_halt(true).0, 0x010F);
}

#[test]
fn cia402_next_controlword_every_state() {
    use DriveState::*;
    let expected = [
        (NotReadyToSwitchOn, None),
        (SwitchOnDisabled, Some(0x0006)),
        (ReadyToSwitchOn, Some(0x0007)),
        (SwitchedOn, Some(0x000F)),
        (OperationEnabled, None),
        (QuickStopActive, Some(0x0000)),
        (FaultReactionActive, None),
        (Fault, Some(0x0080)),
    ];
    for (state, cw) in expected {
        assert_eq!(next_controlword_towards_enabled(state), cw, "{state:?}");
    }
    // Walking the path with a trivial drive model reaches operation enabled.
    let step = |s: DriveState, cw: u16| match (s, cw) {
        (Fault, 0x0080) => SwitchOnDisabled,
        (SwitchOnDisabled, 0x0006) => ReadyToSwitchOn,
        (ReadyToSwitchOn, 0x0007) => SwitchedOn,
        (SwitchedOn, 0x000F) => OperationEnabled,
        (QuickStopActive, 0x0000) => SwitchOnDisabled,
        (s, _) => s,
    };
    for start in [Fault, QuickStopActive, SwitchOnDisabled] {
        let mut s = start;
        for _ in 0..6 {
            if let Some(cw) = next_controlword_towards_enabled(s) {
                s = step(s, cw);
            }
        }
        assert_eq!(s, OperationEnabled, "from {start:?}");
    }
}

#[test]
fn node_id_range() {
    assert_eq!(NodeId::new(0), Err(CanOpenError::InvalidNodeId { node: 0 }));
    assert_eq!(
        NodeId::new(128),
        Err(CanOpenError::InvalidNodeId { node: 128 })
    );
    assert_eq!(NodeId::new(127).map(NodeId::get), Ok(127));
    assert_eq!(
        SdoData::new(&[]),
        Err(CanOpenError::BadSdoDataLength { len: 0 })
    );
    assert_eq!(
        SdoData::new(&[0; 5]),
        Err(CanOpenError::BadSdoDataLength { len: 5 })
    );
}

// ============================================================== slcan

#[test]
fn slcan_frames_literal() {
    let f = CanFrame::new_standard(0x123, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    assert_eq!(SlcanMessage::frame(f).encode(), b"t12380102030405060708\r");
    assert_eq!(
        SlcanMessage::decode(b"t12380102030405060708\r"),
        Ok(SlcanMessage::Frame {
            frame: f,
            timestamp: None
        })
    );
    let lower = SlcanMessage::decode(b"t1a31ab\r").unwrap();
    assert_eq!(
        lower,
        SlcanMessage::frame(CanFrame::new_standard(0x1A3, &[0xAB]).unwrap())
    );
    let ext = CanFrame::new_extended(0x1ABC_DEF0, &[0xDE, 0xAD]).unwrap();
    assert_eq!(SlcanMessage::frame(ext).encode(), b"T1ABCDEF02DEAD\r");
    assert_eq!(
        SlcanMessage::decode(b"T1abcdef02dead\r"),
        Ok(SlcanMessage::frame(ext))
    );
    let rtr = CanFrame::new_remote(CanId::Standard(0x123), 2).unwrap();
    assert_eq!(SlcanMessage::frame(rtr).encode(), b"r1232\r");
    assert_eq!(
        SlcanMessage::decode(b"r1232\r"),
        Ok(SlcanMessage::frame(rtr))
    );
    let ertr = CanFrame::new_remote(CanId::Extended(1), 0).unwrap();
    assert_eq!(SlcanMessage::frame(ertr).encode(), b"R000000010\r");
    let empty = CanFrame::new_standard(0x7FF, &[]).unwrap();
    assert_eq!(SlcanMessage::frame(empty).encode(), b"t7FF0\r");
    // With a timestamp (Z1 on).
    assert_eq!(
        SlcanMessage::decode(b"t123111EA5F\r"),
        Ok(SlcanMessage::Frame {
            frame: CanFrame::new_standard(0x123, &[0x11]).unwrap(),
            timestamp: Some(0xEA5F)
        })
    );
    assert_eq!(
        SlcanMessage::Frame {
            frame: rtr,
            timestamp: Some(0x0102)
        }
        .encode(),
        b"r12320102\r"
    );
}

#[test]
fn slcan_commands_and_replies_literal() {
    let table: [(SlcanMessage, &[u8]); 14] = [
        (SlcanMessage::Open, b"O\r"),
        (SlcanMessage::Close, b"C\r"),
        (SlcanMessage::SetBitrate(Bitrate::K125), b"S4\r"),
        (SlcanMessage::SetBitrate(Bitrate::K500), b"S6\r"),
        (SlcanMessage::SetBitrate(Bitrate::M1), b"S8\r"),
        (SlcanMessage::ReadStatusFlags, b"F\r"),
        (SlcanMessage::ReadVersion, b"V\r"),
        (SlcanMessage::SetTimestamps(false), b"Z0\r"),
        (SlcanMessage::SetTimestamps(true), b"Z1\r"),
        (SlcanMessage::Ok, b"\r"),
        (SlcanMessage::Error, b"\x07"),
        (SlcanMessage::TransmitAck { extended: false }, b"z\r"),
        (SlcanMessage::TransmitAck { extended: true }, b"Z\r"),
        (SlcanMessage::StatusFlags(0xA5), b"FA5\r"),
    ];
    for (msg, bytes) in table {
        assert_eq!(msg.encode(), bytes, "{msg:?}");
        assert_eq!(SlcanMessage::decode(bytes), Ok(msg));
    }
    assert_eq!(
        SlcanMessage::decode(b"V1013\r"),
        Ok(SlcanMessage::Version(*b"1013"))
    );
    assert_eq!(Bitrate::K125.bits_per_second(), 125_000);
    assert_eq!(Bitrate::from_bits_per_second(1_000_000), Some(Bitrate::M1));
    assert_eq!(Bitrate::from_code(9), None);
}

#[test]
fn slcan_rejects_malformed() {
    assert!(matches!(
        SlcanMessage::decode(b"t8000\r"),
        Err(SlcanError::Frame(CanFrameError::IdTooLarge {
            id: 0x800,
            ..
        }))
    ));
    assert_eq!(
        SlcanMessage::decode(b"t1239\r"),
        Err(SlcanError::BadDlc { byte: b'9' })
    );
    assert!(matches!(
        SlcanMessage::decode(b"t1232010\r"),
        Err(SlcanError::BadLength { what: "frame", .. })
    ));
    assert_eq!(
        SlcanMessage::decode(b"t12G0\r"),
        Err(SlcanError::BadHex {
            offset: 3,
            byte: b'G'
        })
    );
    assert_eq!(
        SlcanMessage::decode(b"t1231zz\r"),
        Err(SlcanError::BadHex {
            offset: 5,
            byte: b'z'
        })
    );
    assert_eq!(
        SlcanMessage::decode(b"S9\r"),
        Err(SlcanError::BadBitrate { code: b'9' })
    );
    assert_eq!(
        SlcanMessage::decode(b"X\r"),
        Err(SlcanError::UnknownCommand { byte: b'X' })
    );
    assert_eq!(
        SlcanMessage::decode(b"t1230"),
        Err(SlcanError::MissingTerminator)
    );
    assert_eq!(SlcanMessage::decode(b""), Err(SlcanError::Empty));
    assert!(matches!(
        SlcanMessage::decode(b"T1230\r"),
        Err(SlcanError::BadLength { .. })
    ));
}

#[test]
fn slcan_decoder_resync_and_cap() {
    let mut d = SlcanDecoder::default();
    let out = d.push(b"xx\x00t1230\rz");
    assert_eq!(out.len(), 2);
    assert!(matches!(
        &out[0],
        Err(SlcanError::Discarded { count: 3, .. })
    ));
    assert_eq!(
        out[1],
        Ok(SlcanMessage::frame(
            CanFrame::new_standard(0x123, &[]).unwrap()
        ))
    );
    assert_eq!(d.pending(), 1);
    assert_eq!(
        d.push(b"\r\r\x07"),
        vec![
            Ok(SlcanMessage::TransmitAck { extended: false }),
            Ok(SlcanMessage::Ok),
            Ok(SlcanMessage::Error)
        ]
    );
    // Partial line cut by BEL.
    let out = d.push(b"t12\x07");
    assert!(matches!(
        &out[0],
        Err(SlcanError::Discarded { count: 3, .. })
    ));
    assert_eq!(out[1], Ok(SlcanMessage::Error));
    // Pure garbage line is not mistaken for OK.
    let out = d.push(b"hello\r");
    assert_eq!(out.len(), 1);
    assert!(matches!(
        &out[0],
        Err(SlcanError::Discarded { count: 6, .. })
    ));
    // Over-long line.
    let mut d = SlcanDecoder::new(31);
    let mut junk = vec![b'q'; 40];
    junk.extend_from_slice(b"\rO\r");
    let out = d.push(&junk);
    assert_eq!(
        out,
        vec![
            Err(SlcanError::LineTooLong { max: 31 }),
            Ok(SlcanMessage::Open)
        ]
    );
    assert_eq!(d.discarded_bytes(), 41);
}

// ============================================================== PenMount

#[test]
fn penmount_literal_kernel_layout() {
    // Built by hand per pm_parse_6000(): header 0x70 (0x30 | touch 0x40),
    // x = data[2]*256 + data[1], y = data[4]*256 + data[3],
    // data[5] = ~(sum of data[0..5]) & 0xff (pm_checkpacket()).
    // x = 300 = 0x012C, y = 200 = 0x00C8; sum = 0x70+0x2C+0x01+0xC8+0x00 = 0x165 -> 0x65 -> ~ = 0x9A.
    let bytes = [0x70, 0x2C, 0x01, 0xC8, 0x00, 0x9A];
    let p = PenMountPacket::decode(&bytes).unwrap();
    assert_eq!(
        p,
        PenMountPacket {
            touch: true,
            x: 300,
            y: 200
        }
    );
    assert_eq!(p.encode(), bytes);
    let up = PenMountPacket::new(false, 0, 0).unwrap();
    assert_eq!(up.encode(), [0x30, 0, 0, 0, 0, 0xCF]);
    let max = PenMountPacket::new(true, 511, 255).unwrap();
    assert_eq!(max.encode(), [0x70, 0xFF, 0x01, 0xFF, 0x00, !0x6Fu8]);
    assert_eq!(checksum(&[0x70, 0xFF, 0x01, 0xFF, 0x00]), 0x90);
}

#[test]
fn penmount_rejects_malformed() {
    assert_eq!(
        PenMountPacket::decode(&[0x70, 0x2C, 0x01, 0xC8, 0x00, 0x9B]),
        Err(PenMountError::BadChecksum {
            expected: 0x9A,
            found: 0x9B
        })
    );
    assert_eq!(
        PenMountPacket::decode(&[0x31, 0, 0, 0, 0, 0xCE]),
        Err(PenMountError::BadHeader { byte: 0x31 })
    );
    assert_eq!(
        PenMountPacket::decode(&[0x30, 0x00, 0x02, 0x00, 0x00, 0xCD]),
        Err(PenMountError::OutOfRange {
            axis: Axis::X,
            value: 512,
            max: 511
        })
    );
    assert_eq!(
        PenMountPacket::decode(&[0x30, 0x00, 0x00, 0x00, 0x01, 0xCE]),
        Err(PenMountError::OutOfRange {
            axis: Axis::Y,
            value: 256,
            max: 255
        })
    );
    assert_eq!(
        PenMountPacket::decode(&[0x30, 0, 0]),
        Err(PenMountError::WrongLength { len: 3 })
    );
    assert!(PenMountPacket::new(false, 512, 0).is_err());
    assert!(PenMountPacket::new(false, 0, 256).is_err());
}

#[test]
fn penmount_decoder_resyncs() {
    let a = PenMountPacket::new(true, 300, 200).unwrap().encode();
    let b = PenMountPacket::new(false, 10, 20).unwrap().encode();
    let mut corrupt = a;
    corrupt[5] ^= 0xFF;
    let mut stream = vec![0x00, 0xFF, 0x12];
    stream.extend_from_slice(&a);
    stream.extend_from_slice(&corrupt);
    stream.extend_from_slice(&b);
    let mut d = PenMountDecoder::new();
    let mut got = Vec::new();
    for chunk in stream.chunks(4) {
        got.extend(d.push(chunk));
    }
    assert_eq!(
        got,
        vec![
            PenMountPacket::decode(&a).unwrap(),
            PenMountPacket::decode(&b).unwrap()
        ]
    );
    let s = d.stats();
    assert_eq!(s.good, 2);
    assert_eq!(s.bad_checksum, 1);
    // 3 leading garbage bytes + the 6 bytes of the corrupted packet.
    assert_eq!(s.discarded_bytes, 9);
    assert_eq!(d.pending(), 0);
}

// ============================================================== properties

fn arb_frame() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (0u16..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::new_standard(id, &d).unwrap()),
        (
            0u32..=0x1FFF_FFFF,
            proptest::collection::vec(any::<u8>(), 0..=8)
        )
            .prop_map(|(id, d)| CanFrame::new_extended(id, &d).unwrap()),
        (0u16..=0x7FF, 0u8..=8)
            .prop_map(|(id, n)| CanFrame::new_remote(CanId::Standard(id), n).unwrap()),
        (0u32..=0x1FFF_FFFF, 0u8..=8).prop_map(|(id, n)| CanFrame::new_remote(
            CanId::Extended(id),
            n
        )
        .unwrap()),
    ]
}

fn arb_decimal() -> impl Strategy<Value = Decimal> {
    (-9_999_999i64..=9_999_999, 0u8..=4).prop_map(|(m, s)| Decimal::new(m, s).unwrap())
}

fn arb_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::Nest),
        Just(Command::Where),
        Just(Command::ErrorRead),
        Just(Command::Reset),
        (
            0u8..=9,
            prop_oneof![
                Just(None),
                Just(Some(Acceleration::High)),
                Just(Some(Acceleration::Low))
            ]
        )
            .prop_map(|(l, a)| Command::Speed {
                level: SpeedLevel::new(l).unwrap(),
                accel: a
            }),
        proptest::array::uniform5(arb_decimal()).prop_map(Command::MoveJoints),
        proptest::array::uniform5(arb_decimal()).prop_map(Command::MovePose),
        (1u8..=5, arb_decimal()).prop_map(|(j, a)| Command::MoveJoint {
            joint: JointNumber::new(j).unwrap(),
            angle: a
        }),
    ]
}

fn arb_sdo_data() -> impl Strategy<Value = SdoData> {
    proptest::collection::vec(any::<u8>(), 1..=4).prop_map(|v| SdoData::new(&v).unwrap())
}

fn arb_slcan() -> impl Strategy<Value = SlcanMessage> {
    prop_oneof![
        (arb_frame(), proptest::option::of(any::<u16>()))
            .prop_map(|(frame, timestamp)| SlcanMessage::Frame { frame, timestamp }),
        Just(SlcanMessage::Open),
        Just(SlcanMessage::Close),
        (0u8..=8).prop_map(|c| SlcanMessage::SetBitrate(Bitrate::from_code(c).unwrap())),
        Just(SlcanMessage::ReadStatusFlags),
        Just(SlcanMessage::ReadVersion),
        any::<bool>().prop_map(SlcanMessage::SetTimestamps),
        Just(SlcanMessage::Ok),
        Just(SlcanMessage::Error),
        any::<bool>().prop_map(|extended| SlcanMessage::TransmitAck { extended }),
        any::<u8>().prop_map(SlcanMessage::StatusFlags),
        "[0-9A-Za-z]{4}".prop_map(|s| {
            let b = s.as_bytes();
            SlcanMessage::Version([b[0], b[1], b[2], b[3]])
        }),
    ]
}

fn chunked(bytes: &[u8], cuts: &[usize]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut rest = bytes;
    for &c in cuts {
        if rest.is_empty() {
            break;
        }
        let (a, b) = rest.split_at(c % (rest.len() + 1));
        out.push(a.to_vec());
        rest = b;
    }
    out.push(rest.to_vec());
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    // ---- no panics on random input

    #[test]
    fn can_frame_constructor_never_panics(id in any::<u32>(), ext in any::<bool>(), data in proptest::collection::vec(any::<u8>(), 0..12)) {
        let r = if ext { CanFrame::new_extended(id, &data) } else { CanFrame::new_standard(id as u16, &data) };
        if let Ok(f) = r { prop_assert!(f.data().len() <= 8); }
    }

    #[test]
    fn movemaster_mp_decoder_and_encoder_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..48), pose in proptest::array::uniform5(any::<f64>())) {
        let mut line = b"MP ".to_vec();
        line.extend(tail);
        let _ = Command::decode(&line);
        if let Ok(c) = Command::move_pose(&pose) {
            prop_assert_eq!(Command::decode(&c.encode()), Ok(c));
        }
    }

    #[test]
    fn movemaster_decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = Command::decode(&bytes);
        let _ = WhereReply::decode(&bytes);
        let _ = WhereReply::decode_body(&bytes);
        let _ = ErrorStatus::decode(&bytes);
        let _ = ErrorStatus::decode_body(&bytes);
    }

    #[test]
    fn movemaster_decoders_never_panic_on_plausible_text(s in "[MJSPDWHNTERS0-9+\\-., \r]{0,40}") {
        let _ = Command::decode(s.as_bytes());
        let _ = WhereReply::decode(s.as_bytes());
        let _ = ErrorStatus::decode(s.as_bytes());
    }

    #[test]
    fn line_framer_never_panics(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..40), 0..8), max in 0usize..20) {
        let mut f = LineFramer::new(max);
        for c in &chunks {
            for line in f.push(c).into_iter().flatten() {
                prop_assert!(line.len() <= max.max(1));
                prop_assert!(!line.contains(&b'\r'));
            }
        }
    }

    #[test]
    fn canopen_decoders_never_panic(frame in arb_frame(), payload in proptest::collection::vec(any::<u8>(), 0..10), sw in any::<u16>()) {
        let _ = CanOpenMessage::decode(&frame);
        let _ = Nmt::decode(&frame);
        let _ = Heartbeat::decode(&frame);
        let _ = Emergency::decode(&frame);
        let _ = SdoRequest::decode(&frame);
        let _ = SdoResponse::decode(&frame);
        let _ = SdoRequest::decode_payload(&payload);
        let _ = SdoResponse::decode_payload(&payload);
        let _ = Statusword(sw).state();
    }

    #[test]
    fn slcan_decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..48)) {
        let _ = SlcanMessage::decode(&bytes);
        let mut d = SlcanDecoder::default();
        let _ = d.push(&bytes);
    }

    #[test]
    fn slcan_decoders_never_panic_on_plausible_text(s in "[tTrRSOCFVZz0-9a-fA-F\r\x07]{0,48}") {
        let _ = SlcanMessage::decode(s.as_bytes());
        let mut d = SlcanDecoder::default();
        let _ = d.push(s.as_bytes());
    }

    #[test]
    fn penmount_decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = PenMountPacket::decode(&bytes);
        let mut d = PenMountDecoder::new();
        let got = d.push(&bytes);
        let s = d.stats();
        prop_assert_eq!(s.good as usize, got.len());
        prop_assert!(d.pending() < 6);
        prop_assert_eq!(s.discarded_bytes + 6 * s.good + d.pending() as u64, bytes.len() as u64);
    }

    // ---- round trips

    #[test]
    fn movemaster_command_round_trip(cmd in arb_command()) {
        prop_assert_eq!(Command::decode(&cmd.encode()), Ok(cmd));
    }

    #[test]
    fn movemaster_where_round_trip(v in proptest::array::uniform5(-99_999i64..=99_999)) {
        let r = WhereReply { x: v[0] as f64 / 10.0, y: v[1] as f64 / 10.0, z: v[2] as f64 / 10.0, pitch: v[3] as f64 / 10.0, roll: v[4] as f64 / 10.0 };
        prop_assert_eq!(WhereReply::decode(&r.encode()), Ok(r));
    }

    #[test]
    fn movemaster_error_status_round_trip(code in 0u8..3) {
        let s = ErrorStatus::decode(&[b'0' + code, b'\r']).unwrap();
        prop_assert_eq!(s.code(), code);
        prop_assert_eq!(ErrorStatus::decode(&s.encode()), Ok(s));
    }

    #[test]
    fn line_framer_round_trip(lines in proptest::collection::vec("[ -~]{0,20}", 0..8), cuts in proptest::collection::vec(any::<usize>(), 0..8), crlf in any::<bool>()) {
        let mut stream = Vec::new();
        for l in &lines {
            stream.extend_from_slice(l.as_bytes());
            stream.extend_from_slice(if crlf { b"\r\n" } else { b"\r" });
        }
        let mut f = LineFramer::new(20);
        let mut got = Vec::new();
        for c in chunked(&stream, &cuts) {
            got.extend(f.push(&c));
        }
        let expected: Vec<Result<Vec<u8>, MovemasterError>> = lines.iter().map(|l| Ok(l.as_bytes().to_vec())).collect();
        prop_assert_eq!(got, expected);
    }

    #[test]
    fn sdo_request_round_trip(n in 1u8..=127, index in any::<u16>(), sub in any::<u8>(), data in arb_sdo_data(), code in any::<u32>(), kind in 0u8..3) {
        let req = match kind {
            0 => SdoRequest::Upload { index, sub },
            1 => SdoRequest::Download { index, sub, data },
            _ => SdoRequest::Abort { index, sub, code: SdoAbortCode::from_code(code) },
        };
        let frame = req.encode(node(n));
        prop_assert_eq!(frame.raw_id(), 0x600 + u32::from(n));
        prop_assert_eq!(SdoRequest::decode(&frame), Ok((node(n), req)));
        let classified = matches!(CanOpenMessage::decode(&frame), Ok(CanOpenMessage::SdoRequest { .. }));
        prop_assert!(classified);
    }

    #[test]
    fn sdo_response_round_trip(n in 1u8..=127, index in any::<u16>(), sub in any::<u8>(), data in arb_sdo_data(), code in any::<u32>(), kind in 0u8..3) {
        let resp = match kind {
            0 => SdoResponse::UploadData { index, sub, data },
            1 => SdoResponse::DownloadAck { index, sub },
            _ => SdoResponse::Abort { index, sub, code: SdoAbortCode::from_code(code) },
        };
        let frame = resp.encode(node(n));
        prop_assert_eq!(frame.raw_id(), 0x580 + u32::from(n));
        prop_assert_eq!(SdoResponse::decode(&frame), Ok((node(n), resp)));
    }

    #[test]
    fn nmt_heartbeat_emcy_round_trip(n in 0u8..=127, cs in 0usize..5, st in 0usize..4, code in any::<u16>(), reg in any::<u8>(), m in any::<[u8; 5]>()) {
        let cmds = [NmtCommand::Start, NmtCommand::Stop, NmtCommand::EnterPreOperational, NmtCommand::ResetNode, NmtCommand::ResetCommunication];
        let nmt = Nmt { command: cmds[cs], node: NodeId::new(n).ok() };
        prop_assert_eq!(Nmt::decode(&nmt.encode()), Ok(nmt));
        if let Ok(id) = NodeId::new(n) {
            let states = [NmtState::BootUp, NmtState::Stopped, NmtState::Operational, NmtState::PreOperational];
            let hb = Heartbeat { node: id, state: states[st] };
            prop_assert_eq!(Heartbeat::decode(&hb.encode()), Ok(hb));
            prop_assert_eq!(CanOpenMessage::decode(&hb.encode()), Ok(CanOpenMessage::Heartbeat(hb)));
            let e = Emergency { node: id, error_code: EmcyErrorCode::from_code(code), error_register: reg, manufacturer: m };
            prop_assert_eq!(Emergency::decode(&e.encode()), Ok(e));
            prop_assert_eq!(CanOpenMessage::decode(&e.encode()), Ok(CanOpenMessage::Emergency(e)));
        }
    }

    #[test]
    fn slcan_round_trip(msg in arb_slcan()) {
        prop_assert_eq!(SlcanMessage::decode(&msg.encode()), Ok(msg));
    }

    #[test]
    fn slcan_stream_round_trip(msgs in proptest::collection::vec(arb_slcan(), 0..10), cuts in proptest::collection::vec(any::<usize>(), 0..10)) {
        let stream: Vec<u8> = msgs.iter().flat_map(|m| m.encode()).collect();
        let mut d = SlcanDecoder::default();
        let mut got = Vec::new();
        for c in chunked(&stream, &cuts) {
            got.extend(d.push(&c));
        }
        let expected: Vec<Result<SlcanMessage, SlcanError>> = msgs.into_iter().map(Ok).collect();
        prop_assert_eq!(got, expected);
        prop_assert_eq!(d.discarded_bytes(), 0);
    }

    #[test]
    fn penmount_round_trip(touch in any::<bool>(), x in 0u16..=511, y in 0u16..=255) {
        let p = PenMountPacket::new(touch, x, y).unwrap();
        prop_assert_eq!(PenMountPacket::decode(&p.encode()), Ok(p));
    }

    #[test]
    fn penmount_stream_recovers_after_garbage(
        items in proptest::collection::vec((any::<bool>(), 0u16..=511, 0u16..=255, proptest::collection::vec(any::<u8>(), 0..5)), 0..10),
        cuts in proptest::collection::vec(any::<usize>(), 0..10),
    ) {
        // Garbage between packets never contains a header byte, so every packet must be recovered.
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        let mut garbage_len = 0u64;
        for (t, x, y, g) in &items {
            let g: Vec<u8> = g.iter().copied().filter(|b| b & 0xBF != 0x30).collect();
            garbage_len += g.len() as u64;
            stream.extend_from_slice(&g);
            let p = PenMountPacket::new(*t, *x, *y).unwrap();
            stream.extend_from_slice(&p.encode());
            expected.push(p);
        }
        let mut d = PenMountDecoder::new();
        let mut got = Vec::new();
        for c in chunked(&stream, &cuts) {
            got.extend(d.push(&c));
        }
        prop_assert_eq!(got, expected);
        prop_assert_eq!(d.stats().discarded_bytes, garbage_len);
        prop_assert_eq!(d.stats().bad_checksum, 0);
    }

    #[test]
    fn quantise_sum_property(targets in proptest::collection::vec(-720.0f64..720.0, 1..50), decimals in 0u8..=3) {
        let res = Resolution::new(decimals).unwrap();
        let mut commanded = 0i64;
        let mut sum = 0i64;
        for t in &targets {
            let s = quantise_increment(*t, commanded, res).unwrap();
            sum += s.increment_counts;
            commanded = s.commanded_counts;
        }
        prop_assert_eq!(sum, res.to_counts(*targets.last().unwrap()).unwrap());
    }
}
