//! The VL53L5CX driver over the simulated sensor: init, resolution, frequency, integration time,
//! ranging mode, start/stop, data-ready, result parsing, write chunking, and every fault as a
//! typed error (NACK at each transaction of init, timeouts, wrong chip id, wrong buffer sizes,
//! corrupt result blocks) with the output untouched and the next good frame identical.

use depthor_core::drivers::vl53l5cx::protocol::{self, block, BlockHeader};
use depthor_core::drivers::vl53l5cx::sim::{self, SimVl53l5cx, SimZone};
use depthor_core::drivers::vl53l5cx::{
    results_len, Config, RangingMode, Resolution, ResultsData, ResultsError, Step, UldBuffers,
    Vl53l5cx, Vl53l5cxError,
};
use depthor_core::hal::{DtofSensor, ZoneFrame};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{self, I2c, NoAcknowledgeSource, Operation};

struct NoDelay;
impl DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

/// Counts simulated time so timeouts can be checked.
#[derive(Default)]
struct Clock(u64);
impl DelayNs for &mut Clock {
    fn delay_ns(&mut self, ns: u32) {
        self.0 += u64::from(ns);
    }
}

fn zones(seed: u32) -> [SimZone; 64] {
    core::array::from_fn(|k| {
        let k = k as u32;
        if (k + seed) % 11 == 3 {
            SimZone::NONE
        } else {
            SimZone {
                distance_mm: (300 + 37 * k + 5 * seed) as i16,
                status: if k.is_multiple_of(7) { 9 } else { 5 },
                sigma_mm: (2 + k % 9) as u16,
                signal_kcps: 100 + 3 * k,
                ambient_kcps: 1 + k % 4,
            }
        }
    })
}

type Err = Vl53l5cxError<i2c::ErrorKind>;

fn ready<'a, I: I2c<Error = i2c::ErrorKind>>(
    bus: I,
    io: &'a mut [u8],
    config: Config,
) -> Result<Vl53l5cx<'a, I, NoDelay>, Err> {
    let mut tof = Vl53l5cx::new(bus, NoDelay, sim::stand_in_buffers(), io, config);
    tof.init()?;
    tof.set_resolution(Resolution::R8x8)?;
    tof.set_ranging_frequency_hz(15)?;
    tof.set_integration_time_ms(20)?;
    tof.set_ranging_mode(RangingMode::Continuous)?;
    tof.start_ranging()?;
    Ok(tof)
}

fn check_frame(frame: &ZoneFrame<64>, z: &[SimZone; 64]) {
    assert_eq!((frame.rows, frame.cols), (8, 8));
    assert!(frame.has_sigma && frame.has_signal && frame.has_ambient);
    for (k, zone) in z.iter().enumerate() {
        if zone.status == 255 {
            assert_eq!(frame.status[k], 255, "zone {k}");
            assert_eq!(frame.distance_mm[k], 0.0, "zone {k}");
        } else {
            assert_eq!(frame.status[k], zone.status, "zone {k}");
            assert_eq!(
                frame.distance_mm[k],
                f32::from(zone.distance_mm),
                "zone {k}"
            );
        }
        assert_eq!(frame.sigma_mm[k], f32::from(zone.sigma_mm), "zone {k}");
        assert_eq!(frame.signal_kcps[k], zone.signal_kcps as f32, "zone {k}");
        assert_eq!(frame.ambient_kcps[k], zone.ambient_kcps as f32, "zone {k}");
    }
}

#[test]
fn init_configure_range_and_read_frames() {
    let mut dev = SimVl53l5cx::new();
    dev.set_zones(&zones(0));
    dev.set_latency_polls(3);
    let mut io = [0u8; 1452];
    let mut tof = ready(dev, &mut io, Config::default()).unwrap();
    assert!(tof.i2c().booted());
    assert_eq!(
        tof.i2c().firmware_hash(),
        fnv(&sim::STAND_IN_FIRMWARE),
        "the upload carried the firmware bytes in order"
    );
    assert_eq!(tof.ranging_frequency_hz().unwrap(), 15);
    assert_eq!(tof.integration_time_ms().unwrap(), 20);
    assert_eq!(tof.read_resolution().unwrap(), Resolution::R8x8);
    assert_eq!(tof.i2c().dci(protocol::dci::RANGING_MODE).unwrap()[1], 1);
    assert_eq!(tof.i2c().results_len(), 1440);
    assert_eq!(results_len(Resolution::R8x8), 1440);
    assert_eq!(results_len(Resolution::R4x4), 528);
    let mut frame = ZoneFrame::<64>::new();
    for seed in 0..4 {
        let z = zones(seed);
        tof.i2c_mut().set_zones(&z);
        tof.read_frame(&mut frame).unwrap();
        check_frame(&frame, &z);
        assert_eq!(tof.last_results().silicon_temp_degc, 31);
    }
    assert_eq!(tof.i2c().frames(), 4);
    assert!(
        !tof.check_data_ready().unwrap(),
        "the next frame needs 3 more ticks"
    );
    tof.stop_ranging().unwrap();
    assert!(!tof.i2c().ranging());
    assert!(matches!(
        tof.read_frame(&mut frame),
        Err(Vl53l5cxError::NotRanging)
    ));
    // Ranging again after a stop.
    tof.start_ranging().unwrap();
    tof.read_frame(&mut frame).unwrap();
    check_frame(&frame, &zones(3));
}

#[test]
fn four_by_four_mode() {
    let mut dev = SimVl53l5cx::new();
    dev.set_zones(&zones(1));
    let mut io = [0u8; 600];
    let mut tof = Vl53l5cx::new(
        dev,
        NoDelay,
        sim::stand_in_buffers(),
        &mut io,
        Config::default(),
    );
    tof.init().unwrap();
    assert_eq!(tof.read_resolution().unwrap(), Resolution::R4x4);
    tof.set_ranging_frequency_hz(60).unwrap();
    tof.start_ranging().unwrap();
    assert_eq!(tof.geometry().zones(), 16);
    let mut small = ZoneFrame::<16>::new();
    tof.read_frame(&mut small).unwrap();
    let z = zones(1);
    for (k, zk) in z.iter().enumerate().take(16) {
        let want = if zk.status == 255 {
            0.0
        } else {
            f32::from(zk.distance_mm)
        };
        assert_eq!(small.distance_mm[k], want);
    }
    // 8×8 needs a 1440-byte I/O buffer: refused at start, nothing half done.
    tof.stop_ranging().unwrap();
    tof.set_resolution(Resolution::R8x8).unwrap();
    assert!(matches!(
        tof.start_ranging(),
        Err(Vl53l5cxError::IoBufferTooSmall {
            needed: 1440,
            got: 600
        })
    ));
    // A frame buffer too small for the sensor.
    let mut dev = SimVl53l5cx::new();
    dev.set_zones(&zones(1));
    let mut io = [0u8; 1440];
    let mut tof = ready(dev, &mut io, Config::default()).unwrap();
    assert!(matches!(
        tof.read_frame(&mut small),
        Err(Vl53l5cxError::BufferShape {
            zones: 64,
            capacity: 16
        })
    ));
}

#[test]
fn parameters_out_of_range_are_refused_without_bus_traffic() {
    let mut io = [0u8; 1452];
    let mut tof = ready(SimVl53l5cx::new(), &mut io, Config::default()).unwrap();
    let commands = tof.i2c().commands();
    assert!(matches!(
        tof.set_ranging_frequency_hz(16),
        Err(Vl53l5cxError::InvalidParam(_))
    ));
    assert!(matches!(
        tof.set_ranging_frequency_hz(0),
        Err(Vl53l5cxError::InvalidParam(_))
    ));
    assert!(matches!(
        tof.set_integration_time_ms(1),
        Err(Vl53l5cxError::InvalidParam(_))
    ));
    assert!(matches!(
        tof.set_integration_time_ms(1001),
        Err(Vl53l5cxError::InvalidParam(_))
    ));
    assert_eq!(tof.i2c().commands(), commands);
}

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xCBF2_9CE4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// Records the length of every write and flags writes that start on the page register.
struct WriteLog {
    dev: SimVl53l5cx,
    longest: usize,
    bad_page_writes: usize,
}
impl i2c::ErrorType for WriteLog {
    type Error = i2c::ErrorKind;
}
impl I2c for WriteLog {
    fn transaction(&mut self, a: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        if let [Operation::Write(w)] = ops {
            self.longest = self.longest.max(w.len());
            if w.len() > 3 && w[..2] == [0x7F, 0xFF] {
                self.bad_page_writes += 1;
            }
        }
        self.dev.transaction(a, ops)
    }
}

#[test]
fn writes_are_chunked_to_the_callers_limit_and_frames_do_not_change() {
    let mut reference = None;
    // 7 payload bytes per write puts a chunk boundary on 0x7FFF (32767 = 7 × 4681).
    for max in [4usize, 9, 64, 255, 0] {
        let mut dev = SimVl53l5cx::new();
        dev.set_zones(&zones(2));
        let log = WriteLog {
            dev,
            longest: 0,
            bad_page_writes: 0,
        };
        let mut io = [0u8; 1452];
        let config = Config {
            max_write_len: max,
            ..Config::default()
        };
        let mut tof = ready(log, &mut io, config).unwrap();
        let mut frame = ZoneFrame::<64>::new();
        tof.read_frame(&mut frame).unwrap();
        check_frame(&frame, &zones(2));
        let log = tof.i2c();
        assert_eq!(
            log.dev.firmware_hash(),
            fnv(&sim::STAND_IN_FIRMWARE),
            "max {max}"
        );
        assert!(
            log.longest <= if max == 0 { 1452 } else { max },
            "max {max}: {}",
            log.longest
        );
        assert_eq!(
            log.bad_page_writes, 0,
            "max {max}: a chunk started on the page register"
        );
        match &reference {
            None => reference = Some(frame.clone()),
            Some(r) => assert_eq!(r, &frame),
        }
    }
    // One payload byte per write could not avoid starting a chunk on 0x7FFF: refused.
    let mut io = [0u8; 1452];
    let config = Config {
        max_write_len: 3,
        ..Config::default()
    };
    assert!(matches!(
        ready(SimVl53l5cx::new(), &mut io, config).err(),
        Some(Vl53l5cxError::IoBufferTooSmall { needed: 4, got: 3 })
    ));
}

#[test]
fn wrong_chip_id_and_wrong_buffer_sizes() {
    let mut io = [0u8; 1452];
    let mut dev = SimVl53l5cx::new();
    dev.set_ids(0xF0, 0x01);
    let mut tof = Vl53l5cx::new(
        dev,
        NoDelay,
        sim::stand_in_buffers(),
        &mut io,
        Config::default(),
    );
    assert!(matches!(
        tof.init(),
        Err(Vl53l5cxError::WrongChipId {
            device: 0xF0,
            revision: 0x01
        })
    ));
    assert!(!tof.i2c().booted());

    let st = sim::stand_in_buffers();
    let short_fw = &sim::STAND_IN_FIRMWARE[..protocol::FIRMWARE_LEN - 4];
    let cases: [(UldBuffers<'_>, &str); 4] = [
        (
            UldBuffers {
                firmware: short_fw,
                ..st
            },
            "firmware",
        ),
        (
            UldBuffers {
                default_configuration: &sim::STAND_IN_DEFAULT_CONFIG[1..],
                ..st
            },
            "default configuration",
        ),
        (
            UldBuffers {
                default_xtalk: &[],
                ..st
            },
            "default xtalk",
        ),
        (
            UldBuffers {
                get_nvm_cmd: &sim::STAND_IN_NVM_CMD[..39],
                ..st
            },
            "NVM command",
        ),
    ];
    for (bufs, name) in cases {
        let mut io = [0u8; 1452];
        let mut tof = Vl53l5cx::new(
            SimVl53l5cx::new(),
            NoDelay,
            bufs,
            &mut io,
            Config::default(),
        );
        match tof.init() {
            Err(Vl53l5cxError::BufferSize { which, .. }) => assert_eq!(which, name),
            other => panic!("{name}: {other:?}"),
        }
        assert_eq!(tof.i2c().commands(), 0);
    }
    let mut io = [0u8; 16];
    let mut tof = Vl53l5cx::new(SimVl53l5cx::new(), NoDelay, st, &mut io, Config::default());
    assert!(matches!(
        tof.init(),
        Err(Vl53l5cxError::IoBufferTooSmall { .. })
    ));
}

/// A bus that fails transaction number `fail_at` (counting from 0) in one of several ways.
struct Faulty {
    dev: SimVl53l5cx,
    count: usize,
    fail_at: usize,
    how: How,
}
#[derive(Clone, Copy, Debug)]
enum How {
    Nack,
    /// Drops writes to firmware pages (the upload never reaches the sensor).
    DropFirmware,
    /// The command status word never reads "done".
    StatusStuck,
}
impl i2c::ErrorType for Faulty {
    type Error = i2c::ErrorKind;
}
impl I2c for Faulty {
    fn transaction(&mut self, a: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        let n = self.count;
        self.count += 1;
        match self.how {
            How::Nack if n == self.fail_at => {
                return Err(i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data))
            }
            How::DropFirmware => {
                let mut page = [0u8];
                self.dev.write_read(a, &[0x7F, 0xFF], &mut page)?;
                if (9..=11).contains(&page[0])
                    && matches!(ops, [Operation::Write(w)] if w[..2] != [0x7F, 0xFF])
                {
                    return Ok(());
                }
            }
            How::StatusStuck => {
                if let [Operation::Write(w), Operation::Read(r)] = ops {
                    if w[..] == [0x2C, 0x00] && r.len() == 4 {
                        r.fill(0);
                        return Ok(());
                    }
                }
            }
            How::Nack => {}
        }
        self.dev.transaction(a, ops)
    }
}

fn init_transactions() -> usize {
    let bus = Faulty {
        dev: SimVl53l5cx::new(),
        count: 0,
        fail_at: usize::MAX,
        how: How::Nack,
    };
    let mut io = [0u8; 1452];
    let mut tof = Vl53l5cx::new(
        bus,
        NoDelay,
        sim::stand_in_buffers(),
        &mut io,
        Config::default(),
    );
    tof.init().unwrap();
    tof.i2c().count
}

#[test]
fn a_nack_at_every_init_transaction_is_a_bus_error_naming_its_step_and_init_recovers() {
    let total = init_transactions();
    assert!(total > 100, "{total}");
    let mut steps = Vec::new();
    let good = {
        let mut dev = SimVl53l5cx::new();
        dev.set_zones(&zones(4));
        let mut io = [0u8; 1452];
        let mut tof = ready(dev, &mut io, Config::default()).unwrap();
        let mut f = ZoneFrame::<64>::new();
        tof.read_frame(&mut f).unwrap();
        f
    };
    for fail_at in 0..total {
        let mut dev = SimVl53l5cx::new();
        dev.set_zones(&zones(4));
        let bus = Faulty {
            dev,
            count: 0,
            fail_at,
            how: How::Nack,
        };
        let mut io = [0u8; 1452];
        let mut tof = Vl53l5cx::new(
            bus,
            NoDelay,
            sim::stand_in_buffers(),
            &mut io,
            Config::default(),
        );
        match tof.init() {
            Err(Vl53l5cxError::Bus { step, error }) => {
                assert_eq!(
                    error,
                    i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data)
                );
                if steps.last() != Some(&step) {
                    steps.push(step);
                }
            }
            other => panic!("NACK at transaction {fail_at}: {other:?}"),
        }
        // Every 16th case: the same driver and sensor come up after a retry.
        if fail_at % 16 == 0 || fail_at + 1 == total {
            let mut frame = ZoneFrame::<64>::new();
            tof.init().unwrap();
            tof.set_resolution(Resolution::R8x8).unwrap();
            tof.set_ranging_frequency_hz(15).unwrap();
            tof.set_integration_time_ms(20).unwrap();
            tof.set_ranging_mode(RangingMode::Continuous).unwrap();
            tof.start_ranging().unwrap();
            tof.read_frame(&mut frame).unwrap();
            assert_eq!(frame, good, "after a NACK at transaction {fail_at}");
        }
    }
    use Step::*;
    assert_eq!(
        steps,
        [
            Presence,
            Reboot,
            Boot,
            FirmwareAccess,
            PowerOn,
            FirmwareUpload,
            McuBoot,
            Nvm,
            Offset,
            Xtalk,
            DefaultConfig,
            Dci
        ]
    );
}

#[test]
fn an_upload_that_never_arrives_is_an_mcu_error_and_a_stuck_status_is_a_timeout() {
    let mut io = [0u8; 1452];
    let bus = Faulty {
        dev: SimVl53l5cx::new(),
        count: 0,
        fail_at: 0,
        how: How::DropFirmware,
    };
    let mut tof = Vl53l5cx::new(
        bus,
        NoDelay,
        sim::stand_in_buffers(),
        &mut io,
        Config::default(),
    );
    assert!(matches!(
        tof.init(),
        Err(Vl53l5cxError::Mcu {
            step: Step::McuBoot,
            code: sim::BOOT_ERROR_CODE
        })
    ));

    let mut io = [0u8; 1452];
    let mut clock = Clock::default();
    let bus = Faulty {
        dev: SimVl53l5cx::new(),
        count: 0,
        fail_at: 0,
        how: How::StatusStuck,
    };
    let mut tof = Vl53l5cx::new(
        bus,
        &mut clock,
        sim::stand_in_buffers(),
        &mut io,
        Config::default(),
    );
    assert!(matches!(tof.init(), Err(Vl53l5cxError::Timeout(Step::Nvm))));
    let _ = tof.release();
    // The ULD's 2 s (200 polls × 10 ms) plus the boot waits.
    assert!(
        (2_000_000_000..2_200_000_000).contains(&clock.0),
        "{}",
        clock.0
    );
}

#[test]
fn no_frame_in_time_is_a_timeout() {
    let mut dev = SimVl53l5cx::new();
    dev.set_latency_polls(u32::MAX);
    let mut io = [0u8; 1452];
    let config = Config {
        frame_timeout_us: 5_000,
        ..Config::default()
    };
    let mut tof = ready(dev, &mut io, config).unwrap();
    let mut frame = ZoneFrame::<64>::new();
    assert!(matches!(
        tof.read_frame(&mut frame),
        Err(Vl53l5cxError::Timeout(Step::DataReady))
    ));
    assert_eq!(frame, ZoneFrame::<64>::new(), "frame written");
}

/// Wire bytes of a results buffer: preamble, blocks (logical bytes), footer.
fn results(blocks: &[(u32, Vec<u8>)]) -> Vec<u8> {
    let mut logical = vec![0u8; 16];
    for (h, data) in blocks {
        logical.extend_from_slice(&h.to_le_bytes());
        logical.extend_from_slice(data);
    }
    logical.extend_from_slice(&[0x0F, 0, 0, 0, 0, 0, 0, 0]);
    let mut wire: Vec<u8> = logical
        .chunks(4)
        .flat_map(|w| w.iter().rev().copied())
        .collect();
    wire[..4].copy_from_slice(&[7, 5, 5, 0x10]);
    wire
}

fn hdr(idx: u16, kind: u8, size: u16) -> u32 {
    BlockHeader { kind, size, idx }.word()
}

#[test]
fn result_blocks_decode_in_st_units_and_corrupt_ones_are_refused() {
    let d: Vec<u8> = (0..16i16)
        .flat_map(|k| (k * 400 - 6).to_le_bytes())
        .collect();
    let s: Vec<u8> = (0..16u8).map(|k| if k == 2 { 9 } else { 5 }).collect();
    let nb: Vec<u8> = (0..16u8).map(|k| u8::from(k != 3)).collect();
    let sig: Vec<u8> = (0..16u16)
        .flat_map(|k| (k * 128 + 127).to_le_bytes())
        .collect();
    let good = results(&[
        (
            hdr(block::METADATA, 0, 12),
            vec![0, 0, 0, 0, 0, 0, 0, 0, 0xFE, 0, 0, 0],
        ),
        (hdr(0x1234, 0, 8), vec![9; 8]), // unknown blocks are skipped
        (hdr(block::NB_TARGET, 1, 16), nb),
        (hdr(block::SIGMA, 2, 16), sig),
        (hdr(block::DISTANCE, 2, 16), d),
        (hdr(block::TARGET_STATUS, 1, 16), s),
    ]);
    let mut out = ResultsData::new();
    depthor_core::drivers::vl53l5cx::decode_results(&good, 16, &mut out).unwrap();
    assert_eq!(out.stream_count, 7);
    assert_eq!(out.silicon_temp_degc, -2);
    assert_eq!(out.distance_mm[0], 0, "-6 / 4 = -1, clamped to 0");
    assert_eq!(out.distance_mm[1], 98, "394 / 4 truncated");
    assert_eq!(out.range_sigma_mm[5], 5);
    assert_eq!(out.target_status[2], 9);
    assert_eq!(out.target_status[3], 255, "no target detected");
    assert!(out.has.sigma && !out.has.signal && !out.has.ambient);

    let before = out.clone();
    let mut corrupt = Vec::new();
    // A per-zone block with the wrong zone count.
    corrupt.push((
        results(&[
            (hdr(block::DISTANCE, 2, 64), vec![0; 128]),
            (hdr(block::TARGET_STATUS, 1, 16), vec![5; 16]),
        ]),
        ResultsError::BadBlock {
            idx: block::DISTANCE,
        },
    ));
    // A header whose payload runs past the footer.
    let mut t = good.clone();
    t[16..20].copy_from_slice(&hdr(block::METADATA, 0, 0xFF0).to_be_bytes());
    corrupt.push((t, ResultsError::Truncated { at: 16 }));
    // A payload that is not a whole number of words.
    let mut t = good.clone();
    t[16..20].copy_from_slice(&hdr(block::METADATA, 0, 13).to_be_bytes());
    corrupt.push((t, ResultsError::Misaligned { at: 16 }));
    // No distance block.
    corrupt.push((
        results(&[(hdr(block::TARGET_STATUS, 1, 16), vec![5; 16])]),
        ResultsError::Missing {
            idx: block::DISTANCE,
        },
    ));
    corrupt.push((
        good[..24].to_vec(),
        ResultsError::Missing {
            idx: block::DISTANCE,
        },
    ));
    corrupt.push((good[..10].to_vec(), ResultsError::TooShort));
    for (bytes, want) in corrupt {
        assert_eq!(
            depthor_core::drivers::vl53l5cx::decode_results(&bytes, 16, &mut out),
            Err(want)
        );
        assert_eq!(out, before, "{want:?}: output written");
    }
}

/// Corrupts the block header of the next results read once when armed.
struct CorruptOnce {
    dev: SimVl53l5cx,
    armed: bool,
}
impl i2c::ErrorType for CorruptOnce {
    type Error = i2c::ErrorKind;
}
impl I2c for CorruptOnce {
    fn transaction(&mut self, a: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        self.dev.transaction(a, ops)?;
        if let [Operation::Write([0, 0]), Operation::Read(r)] = ops {
            if r.len() > 4 && self.armed {
                self.armed = false;
                r[16..20].copy_from_slice(&[0xD3, 0x3C, 0x7F, 0xF2]); // distance, 0x7FF zones
            }
        }
        Ok(())
    }
}

#[test]
fn a_corrupt_result_header_is_bad_data_and_the_next_frame_is_identical() {
    let mut dev = SimVl53l5cx::new();
    dev.set_zones(&zones(5));
    let mut io = [0u8; 1452];
    let mut tof = ready(
        CorruptOnce { dev, armed: false },
        &mut io,
        Config::default(),
    )
    .unwrap();
    let mut reference = ZoneFrame::<64>::new();
    tof.read_frame(&mut reference).unwrap();
    let mut frame = ZoneFrame::<64>::new();
    tof.i2c_mut().armed = true;
    let err = tof.read_frame(&mut frame).unwrap_err();
    assert!(matches!(err, Vl53l5cxError::BadResults(_)), "{err:?}");
    assert_eq!(
        depthor_core::hal::Error::kind(&err),
        depthor_core::hal::ErrorKind::BadData
    );
    assert_eq!(frame, ZoneFrame::<64>::new(), "frame written");
    tof.read_frame(&mut frame).unwrap();
    assert_eq!(frame, reference);
}

/// A bus whose every read returns bytes from a fixed random stream (a broken or foreign device).
struct Noise {
    bytes: Vec<u8>,
    at: usize,
}
impl i2c::ErrorType for Noise {
    type Error = i2c::ErrorKind;
}
impl I2c for Noise {
    fn transaction(&mut self, _a: u8, ops: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        for op in ops {
            if let Operation::Read(r) = op {
                for b in r.iter_mut() {
                    *b = self
                        .bytes
                        .get(self.at % self.bytes.len().max(1))
                        .copied()
                        .unwrap_or(0);
                    self.at += 1;
                }
            }
        }
        Ok(())
    }
}

mod never_panics {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Any bytes decode to a result or an error; on error the output is untouched.
        #[test]
        fn decode_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..1600), eight in any::<bool>()) {
            let zones = if eight { 64 } else { 16 };
            let mut out = ResultsData::new();
            out.distance_mm[0] = 1234;
            let before = out.clone();
            if depthor_core::drivers::vl53l5cx::decode_results(&bytes, zones, &mut out).is_err() {
                prop_assert_eq!(out, before);
            }
        }

        /// Corrupt the block headers of real results: never a panic, never a wrong zone count.
        #[test]
        fn decode_corrupted_results(flips in proptest::collection::vec((16usize..1432, any::<u8>()), 1..8)) {
            let mut dev = SimVl53l5cx::new();
            dev.set_zones(&zones(6));
            let mut io = [0u8; 1452];
            let mut tof = ready(dev, &mut io, Config::default()).unwrap();
            let mut frame = ZoneFrame::<64>::new();
            tof.read_frame(&mut frame).unwrap();
            let mut buf = vec![0u8; 1440];
            tof.i2c_mut().write_read(0x29, &[0, 0], &mut buf).unwrap();
            for (at, v) in flips {
                buf[at] = v;
            }
            let mut out = ResultsData::new();
            if depthor_core::drivers::vl53l5cx::decode_results(&buf, 64, &mut out).is_ok() {
                prop_assert_eq!(out.zones, 64);
            }
        }

        /// The driver over a device that answers noise: typed errors (or a frame), no panic.
        #[test]
        fn driver_on_noise(bytes in proptest::collection::vec(any::<u8>(), 1..64)) {
            let mut io = [0u8; 1452];
            let mut tof = Vl53l5cx::new(Noise { bytes, at: 0 }, NoDelay, sim::stand_in_buffers(), &mut io, Config::default());
            let _ = tof.init();
            let _ = tof.set_resolution(Resolution::R8x8);
            let _ = tof.start_ranging();
            let mut frame = ZoneFrame::<64>::new();
            let _ = tof.read_frame(&mut frame);
            let _ = tof.stop_ranging();
        }
    }
}

/// The seeds of the `vl53l5cx_results` and `vl53l5cx_driver` fuzz targets
/// (`core/fuzz/seeds/<target>/`; byte layouts at the top of `core/fuzz/fuzz_targets/<target>.rs`)
/// are current: the results seeds are the wire bytes the simulated sensor sends for a 4×4 and an
/// 8×8 frame (the driver's I/O buffer after `read_frame`) behind the target's zone-count byte,
/// and they decode. Rewrite them with `DEPTHOR_WRITE_FUZZ_SEEDS=1 cargo test -p depthor-core
/// --test vl53l5cx fuzz_seed`.
#[test]
fn fuzz_seeds_are_the_simulated_sensors_frames() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let mut seeds: Vec<(&str, &str, Vec<u8>)> = Vec::new();
    for (name, eight, mode, seed) in [("sim_4x4", false, 0u8, 3u32), ("sim_8x8", true, 1, 7)] {
        let mut device = SimVl53l5cx::new();
        device.set_zones(&zones(seed));
        let mut io = [0u8; 1452];
        let mut tof = Vl53l5cx::new(
            device,
            NoDelay,
            sim::stand_in_buffers(),
            &mut io,
            Config::default(),
        );
        tof.init().unwrap();
        let resolution = if eight {
            Resolution::R8x8
        } else {
            Resolution::R4x4
        };
        tof.set_resolution(resolution).unwrap();
        tof.start_ranging().unwrap();
        let mut frame = ZoneFrame::<64>::new();
        tof.read_frame(&mut frame).unwrap();
        let _ = tof.release(); // ends the borrow of `io`, which holds the last results
        let len = results_len(resolution);
        let buf = &io[..len];
        let mut out = ResultsData::new();
        depthor_core::drivers::vl53l5cx::decode_results(
            buf,
            usize::from(resolution.zones()),
            &mut out,
        )
        .unwrap();
        let mut seed = vec![mode];
        seed.extend_from_slice(buf);
        seeds.push(("vl53l5cx_results", name, seed));
    }
    // Driver seeds: `cfg, arg, skip, zone seed`, no control bytes (a clean bus): a warm 4×4
    // session reading 2 frames; init through the bus, 8×8, settings at 10 Hz, 4 frames, stop.
    seeds.push((
        "vl53l5cx_driver",
        "warm_4x4_2frames",
        vec![0b0000_0100, 0, 0, 0, 3, 0, 0, 0],
    ));
    seeds.push((
        "vl53l5cx_driver",
        "init_8x8_settings_4frames_stop",
        vec![0b0110_1111, 10, 0, 0, 7, 0, 0, 0],
    ));
    for (target, name, seed) in &seeds {
        let path = dir.join(target).join(name);
        if std::env::var_os("DEPTHOR_WRITE_FUZZ_SEEDS").is_some() {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, seed).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap();
        assert!(
            &on_disk == seed,
            "{} is stale: rewrite it (see the doc)",
            path.display()
        );
    }
}
