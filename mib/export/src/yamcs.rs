//! A complete Yamcs 5.12 instance generated from the MIB (`ground mib export --format
//! yamcs DIR`): server and instance configuration, the realtime processor, one MDB (XTCE)
//! per robot, the PUS 5 event templates.
//!
//! Per robot N (APID 0x100 + N), by default over the authenticated space link ([`Links::Frames`],
//! `mib::link`): a TC frame link `tc_robot_N` (Yamcs' `UdpTcFrameLink` to the obsw's
//! `--frame-udp` port, COP-1 with FOP-1 driven by the CLCW, SDLS AES-256-GCM with the uplink
//! key) and a TM frame link `tm_robot_N` (`UdpTmFrameLink`, Yamcs listens; the obsw's
//! `--frame-tm-to` points at it; SDLS with the downlink key, anti-replay on). The lab option
//! ([`Links::LabPackets`], `--format yamcs-lab`) writes bare space packets over UDP instead
//! (`--udp` / `--tm-dest`, no authentication). Both: PUS pre- and post-processing with the packet error control (CRC-16/CCITT-FALSE,
//! Yamcs' `CRC-16-CCIIT`), the MDB `/MMIC_I_ROBOT_N` and a `PusEventDecoder` on that
//! robot's TM. The MDB is the XTCE of [`super::xtce_document_for`] with the additions a
//! Yamcs operator needs (the `Yamcs` flavour of the XTCE exporter):
//! - `HK_SID` and `EVENT_ID` are enumerated (PUS event decoder, readable SIDs);
//! - the CDS short time stamp of every TM is decoded by plain XTCE: `TM_TIME_DAYS` is an
//!   absolute time (UNIX epoch, offset and scale of a day) and `TM_TIME_MS` an absolute
//!   time offset from it, so `TM_TIME_MS` reads as the on-board time (Yamcs' PUS
//!   preprocessor reads only CUC, fixed or float64 times: packets carry the reception
//!   time as generation time, `useLocalGenerationTime`);
//! - one container shared by every TM[1,x] with the request ID (`VERIFICATION_*`), so
//!   that `org.yamcs.pus.Pus1Verifier` verifies acceptance, start and completion of every
//!   command and names the failure code;
//! - TC header fields are no operator arguments: sequence count and packet length are
//!   written by `PusCommandPostprocessor`, the acknowledgement flags come from the MIB
//!   ([`mib::tc::TcDef::ack_flags`]).

use std::fmt::Write as _;
use std::str::FromStr;

use super::flavour::Flavour;
use super::headers::HeaderField;
use super::xml::{esc, Xml};
use super::xtce::{self, enumerated_type, parameter};
use mib::events::{EventDef, EVENTS};
use mib::headers::{PRIMARY_HEADER as HEADER_PRIMARY, TM_SEC_HEADER as HEADER_TM_SEC};
use mib::layout::Item;
use mib::layout::{Field, Names, REQUEST_ID};
use mib::modes::NodeKind;
use mib::tc::{TmDef, TMS};
use mib::types::PType;
use mib::{apid, config};

/// Name of the Yamcs instance.
pub const INSTANCE: &str = "mmic";
/// Port of Yamcs' web server and REST API.
pub const HTTP_PORT: u16 = 8090;
/// Yamcs listens for robot N's TM (frames, or packets in the lab) on UDP port `TM_BASE_PORT + N`.
pub const TM_BASE_PORT: u16 = 10_000;
/// Yamcs sends robot N's TC frames to UDP port `FRAME_BASE_PORT + N` (`obsw --frame-udp`).
pub use mib::host_config::FRAME_BASE_PORT;
/// Directory of the SDLS key files, relative to the instance directory (Yamcs runs there).
pub const KEY_DIR: &str = "etc/keys";

/// What the links of the instance carry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Links {
    /// The space link: TC frames with COP-1 and TM frames, both SDLS-protected.
    #[default]
    Frames,
    /// Lab only: bare space packets over UDP, no authentication, no COP-1.
    LabPackets,
}

/// Key file of robot `n`'s uplink (TC, SPI `spi`), relative to the instance directory: 32
/// raw bytes, the same key as the obsw's `--tc-key`. The layout under [`KEY_DIR`] is the
/// one `ground keys create` makes (`robot-N/tc-spiS.key`), so a key directory can be
/// copied in as it is (`scripts/yamcs.sh keys`).
pub fn tc_key_file(n: u8, spi: u16) -> String {
    format!("{KEY_DIR}/robot-{n}/tc-spi{spi}.key")
}
/// Key file of robot `n`'s downlink (TM, SPI `spi`): the obsw's `--tm-key`.
pub fn tm_key_file(n: u8, spi: u16) -> String {
    format!("{KEY_DIR}/robot-{n}/tm-spi{spi}.key")
}
/// Prefix of the shared request-ID parameters of TM[1,x].
pub const VERIFICATION: &str = "VERIFICATION";
/// Seconds after release within which each verification stage must be reported.
pub const ACCEPTANCE_WINDOW_S: u32 = 5;
pub const START_WINDOW_S: u32 = 10;
/// Completion: robot actions (reconfigurations) take minutes.
pub const COMPLETION_WINDOW_S: u32 = 600;

/// A set of robot numbers (1..=254).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RobotSet([u64; 4]);

impl RobotSet {
    pub const EMPTY: RobotSet = RobotSet([0; 4]);
    /// Only robot `n` (the default robot if `n` is out of range).
    pub const fn one(n: u8) -> RobotSet {
        let n = if apid::robot_apid(n).is_some() {
            n
        } else {
            apid::DEFAULT_ROBOT
        };
        let mut w = [0u64; 4];
        w[(n / 64) as usize] = 1 << (n % 64);
        RobotSet(w)
    }
    /// Adds robot `n`; false if `n` is not a robot number.
    pub fn insert(&mut self, n: u8) -> bool {
        if apid::robot_apid(n).is_none() {
            return false;
        }
        self.0[(n / 64) as usize] |= 1 << (n % 64);
        true
    }
    pub fn contains(&self, n: u8) -> bool {
        self.0[(n / 64) as usize] & (1 << (n % 64)) != 0
    }
    /// Robot numbers in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = u8> + '_ {
        (apid::ROBOT_MIN..=apid::ROBOT_MAX).filter(|n| self.contains(*n))
    }
    pub fn is_empty(&self) -> bool {
        self.iter().next().is_none()
    }
}

impl FromStr for RobotSet {
    type Err = String;
    /// "1", "1,2,5", "1-4,7".
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut set = RobotSet::EMPTY;
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let num = |t: &str| {
                t.trim()
                    .parse::<u8>()
                    .ok()
                    .filter(|n| apid::robot_apid(*n).is_some())
                    .ok_or_else(|| {
                        format!(
                            "'{t}' is not a robot number ({}..={})",
                            apid::ROBOT_MIN,
                            apid::ROBOT_MAX
                        )
                    })
            };
            let (lo, hi) = match part.split_once('-') {
                Some((a, b)) => (num(a)?, num(b)?),
                None => (num(part)?, num(part)?),
            };
            if lo > hi {
                return Err(format!("'{part}': empty range"));
            }
            for n in lo..=hi {
                set.insert(n);
            }
        }
        if set.is_empty() {
            return Err(format!("'{s}': no robot"));
        }
        Ok(set)
    }
}

/// One robot of the instance and where its links go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct YamcsRobot {
    pub robot: u8,
    /// Host and UDP port of the obsw's TC socket: `obsw --frame-udp` ([`Links::Frames`]),
    /// `obsw --udp` ([`Links::LabPackets`]).
    pub tc_host: String,
    pub tc_port: u16,
    /// UDP port on which Yamcs receives this robot's TM: `obsw --frame-tm-to` (frames),
    /// `obsw --tm-dest` (lab).
    pub tm_port: u16,
}

impl YamcsRobot {
    /// Robot `n` with the default ports on the loopback: TC frames to `FRAME_BASE_PORT + n`
    /// (lab: packets to the obsw's default port [`mib::host_config::robot_port`]), TM on
    /// `TM_BASE_PORT + n`.
    pub fn default_for(n: u8, links: Links) -> YamcsRobot {
        YamcsRobot {
            robot: n,
            tc_host: "127.0.0.1".into(),
            tc_port: match links {
                Links::Frames => FRAME_BASE_PORT + n as u16,
                Links::LabPackets => mib::host_config::robot_port(n),
            },
            tm_port: TM_BASE_PORT + n as u16,
        }
    }
    fn space_system(&self) -> String {
        format!("MMIC_I_ROBOT_{}", self.robot)
    }
}

/// Everything the generated instance depends on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct YamcsSetup {
    pub instance: String,
    /// Address and port of Yamcs' web server.
    pub http_address: String,
    pub http_port: u16,
    pub robots: Vec<YamcsRobot>,
    pub links: Links,
}

impl YamcsSetup {
    /// The robots of `set` over the space link with the default ports, web server on
    /// 127.0.0.1:8090.
    pub fn for_robots(set: RobotSet) -> YamcsSetup {
        Self::with_links(set, Links::Frames)
    }
    /// The robots of `set` over `links` with the default ports.
    pub fn with_links(set: RobotSet, links: Links) -> YamcsSetup {
        YamcsSetup {
            instance: INSTANCE.into(),
            http_address: "127.0.0.1".into(),
            http_port: HTTP_PORT,
            robots: set.iter().map(|n| YamcsRobot::default_for(n, links)).collect(),
            links,
        }
    }
}

/// MDB file of robot `n`, relative to the instance directory.
pub fn mdb_file(n: u8) -> String {
    format!("mdb/mmic-i-robot-{n}.xml")
}
/// Event templates, relative to the instance directory.
pub const EVENTS_FILE: &str = "etc/events.json";

/// The files of a Yamcs instance for `setup`: (path relative to the instance directory,
/// content). Yamcs is started in that directory (`--etc-dir etc`; the MDB and template
/// paths in the configuration are relative to it).
pub fn yamcs_instance(setup: &YamcsSetup) -> Vec<(String, String)> {
    let mut files = vec![
        ("etc/yamcs.yaml".to_string(), server_yaml(setup)),
        (format!("etc/yamcs.{}.yaml", setup.instance), instance_yaml(setup)),
        ("etc/processor.yaml".to_string(), PROCESSOR_YAML.to_string()),
        (
            EVENTS_FILE.to_string(),
            events_json(&setup.robots.iter().map(|r| r.robot).collect::<Vec<_>>()),
        ),
    ];
    if setup.links == Links::Frames {
        files.push((CFDP_SQL_FILE.to_string(), cfdp_sql(setup)));
    }
    for r in &setup.robots {
        files.push((mdb_file(r.robot), yamcs_xtce(r.robot)));
    }
    files
}

/// The XTCE of robot `n` as the Yamcs MDB.
pub fn yamcs_xtce(n: u8) -> String {
    xtce::document(n, &YAMCS)
}

/// The Yamcs MDB's XTCE: enumerated event and SID fields, on-board time as absolute times,
/// a shared request-ID container, command verifiers, header fields fixed or assigned
/// rather than operator arguments, and the modules' mode names in a space system of their
/// own.
const YAMCS: Flavour = Flavour {
    header_type,
    id_types: Some(id_types),
    tm: mode_tm,
    event_param_type: robot_mode_type,
    event_containers: mode_event_containers,
    extra_types,
    extra_params,
    extra_containers,
    tc_header_fixed,
    assign_ack_flags: true,
    verifiers,
    space_systems: module_modes_space_system,
};

fn server_yaml(s: &YamcsSetup) -> String {
    format!(
        "# Generated from the MMIC-I MIB (crate mib {ver}): do not edit, regenerate with\n\
         # `ground mib export --format yamcs --out DIR`.\n\
         services:\n  - class: org.yamcs.http.HttpServer\n    args:\n      address: {addr}\n      port: {port}\n\
         instances:\n  - {inst}\n\
         # Overridden by `--data-dir` (scripts/yamcs.sh).\n\
         dataDir: yamcs-data\n\
         yamcs-web:\n  tag: MMIC-I\n{buckets}",
        ver = env!("CARGO_PKG_VERSION"),
        addr = s.http_address,
        port = s.http_port,
        inst = s.instance,
        buckets = match s.links {
            Links::Frames => format!(
                "# File transfer (CFDP, docs/files.md): folders of the instance directory, so an operator\n\
                 # can put a file to upload into {UPLOAD_DIR}/ and find the files that came down in {DOWNLOAD_DIR}/.\n\
                 buckets:\n  - name: {UPLOAD_BUCKET}\n    path: {UPLOAD_DIR}\n  \
                 - name: {DOWNLOAD_BUCKET}\n    path: {DOWNLOAD_DIR}\n"
            ),
            Links::LabPackets => String::new(),
        }
    )
}

fn instance_yaml(s: &YamcsSetup) -> String {
    let mut y = String::new();
    let _ = writeln!(
        y,
        "# Generated from the MMIC-I MIB (crate mib {}): Yamcs instance '{}' for robot(s) {}.\n\
         # Links: {}",
        env!("CARGO_PKG_VERSION"),
        s.instance,
        s.robots
            .iter()
            .map(|r| r.robot.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        match s.links {
            Links::Frames => "TC and TM transfer frames over UDP, COP-1, SDLS AES-256-GCM (docs/space-link.md).",
            Links::LabPackets =>
                "LAB ONLY: bare CCSDS space packets over UDP, one datagram per packet, no authentication.",
        }
    );
    y.push_str(
        "services:\n  - class: org.yamcs.archive.XtceTmRecorder\n  - class: org.yamcs.archive.ParameterRecorder\n  \
         - class: org.yamcs.archive.AlarmRecorder\n  - class: org.yamcs.archive.EventRecorder\n  \
         - class: org.yamcs.archive.ReplayServer\n  - class: org.yamcs.archive.CommandHistoryRecorder\n  \
         - class: org.yamcs.parameterarchive.ParameterArchive\n  \
         - class: org.yamcs.ProcessorCreatorService\n    args:\n      name: realtime\n      type: realtime\n",
    );
    for r in &s.robots {
        let _ = write!(
            y,
            "  - class: org.yamcs.pus.PusEventDecoder\n    name: events_robot_{n}\n    args:\n      \
             eventIdParameter: /{ss}/EVENT_ID\n      eventTemplateFile: {EVENTS_FILE}\n      \
             realtimeStreams: [tm_robot_{n}]\n",
            n = r.robot,
            ss = r.space_system()
        );
    }
    if s.links == Links::Frames {
        cfdp_service(&mut y, s);
    }
    y.push_str("dataLinks:\n");
    for r in &s.robots {
        match s.links {
            Links::Frames => frame_links(&mut y, r),
            Links::LabPackets => packet_links(&mut y, r),
        }
    }
    y.push_str("mdb:\n");
    for r in &s.robots {
        let _ = writeln!(y, "  - type: xtce\n    spec: {}", mdb_file(r.robot));
    }
    y.push_str("streamConfig:\n  tm:\n");
    for r in &s.robots {
        let _ = writeln!(
            y,
            "    - name: tm_robot_{n}\n      processor: realtime\n      rootContainer: /{ss}/CCSDSPacket",
            n = r.robot,
            ss = r.space_system()
        );
        if s.links == Links::Frames {
            // Archived as CCSDS packets; no processor: the CFDP service reads them (etc/cfdp.sql).
            let _ = writeln!(
                y,
                "    - name: {files}\n      rootContainer: /{ss}/CCSDSPacket",
                files = files_stream(r.robot),
                ss = r.space_system()
            );
        }
    }
    y.push_str(
        "  invalidTm: invalid_tm_stream\n  cmdHist: [cmdhist_realtime, cmdhist_dump]\n  \
         event: [events_realtime, events_dump]\n  param: [pp_realtime, sys_param, proc_param]\n  \
         parameterAlarm: [alarms_realtime]\n  eventAlarm: [event_alarms_realtime]\n",
    );
    y.push_str("  tc:\n");
    for r in &s.robots {
        let _ = writeln!(
            y,
            "    - name: tc_robot_{n}\n      processor: realtime\n      tcPatterns: [\"/{ss}/.*\"]",
            n = r.robot,
            ss = r.space_system()
        );
    }
    if s.links == Links::Frames {
        // After the TC streams it inserts into.
        let _ = writeln!(y, "  sqlFile: {CFDP_SQL_FILE}");
    }
    y
}

/// The PUS packet pre-processor of a TM link or VC (CRC check, reception time).
fn pus_preprocessor(indent: &str) -> String {
    format!(
        "{indent}packetPreprocessorClassName: org.yamcs.pus.PusPacketPreprocessor\n{indent}packetPreprocessorArgs:\n\
         {indent}  errorDetection:\n{indent}    type: CRC-16-CCIIT\n\
         {indent}  # CDS short time: not a time format of the PUS preprocessor; the on-board time is\n\
         {indent}  # the parameter TM_TIME_MS (see docs/yamcs.md).\n{indent}  useLocalGenerationTime: true\n"
    )
}

/// The PUS command post-processor of a TC link or VC (sequence count, length, CRC), and
/// its TC[11,4] wrapping for the command option `pus11ScheduleAt` in the form the obsw
/// accepts (`mib::tc::sched_cuc`: CUC release time with an implicit P-field, CRC).
fn pus_postprocessor(indent: &str) -> String {
    format!(
        "{indent}commandPostprocessorClassName: org.yamcs.pus.PusCommandPostprocessor\n\
         {indent}commandPostprocessorArgs:\n{indent}  errorDetection:\n{indent}    type: CRC-16-CCIIT\n\
         {indent}  # TC[11,4] for \"Schedule Time\" (pus11ScheduleAt): mib::tc::sched_cuc\n\
         {indent}  pus11Crc: true\n{indent}  timeEncoding:\n{indent}    pfield: {pfield}\n\
         {indent}    implicitPfield: true\n",
        pfield = mib::tc::sched_cuc::PFIELD,
    )
}

/// Lab links: bare space packets over UDP.
fn packet_links(y: &mut String, r: &YamcsRobot) {
    let _ = write!(
        y,
        "  - name: tm_robot_{n}\n    class: org.yamcs.tctm.UdpTmDataLink\n    stream: tm_robot_{n}\n    \
         port: {tm}\n    maxLength: {max}\n{pre}  \
         - name: tc_robot_{n}\n    class: org.yamcs.tctm.UdpTcDataLink\n    stream: tc_robot_{n}\n    \
         host: {host}\n    port: {tc}\n{post}",
        n = r.robot,
        tm = r.tm_port,
        max = config::MAX_PACKET_LEN,
        host = r.tc_host,
        tc = r.tc_port,
        pre = pus_preprocessor("    "),
        post = pus_postprocessor("    "),
    );
}

/// One SDLS security association of a frame link.
fn sdls_sa(y: &mut String, spi: u16, key_file: &str, rx_args: &str) {
    let _ = write!(
        y,
        "      - spi: {spi}\n        class: org.yamcs.security.sdls.SecurityAssociationAes256Gcm128Factory\n        \
         args:\n          keyFile: {key_file}\n{rx_args}"
    );
}

/// The space link (`mib::link`): TC frames with COP-1 and TM frames, SDLS both ways.
fn frame_links(y: &mut String, r: &YamcsRobot) {
    use mib::link::{cop1, sdls, tc_frame, tc_vc, tm_frame, tm_vc, SCID};
    let n = r.robot;
    let tc_spi = sdls::TC_SPIS[0];
    let tm_spi = sdls::TM_SPIS[0];
    // FOP-1 timer in whole seconds (Yamcs' unit), never shorter than ours.
    let t1_s = cop1::FOP_T1_MS.div_ceil(1000);
    let _ = write!(
        y,
        "  - name: tc_robot_{n}\n    class: org.yamcs.tctm.ccsds.UdpTcFrameLink\n    host: {host}\n    port: {port}\n    \
         spacecraftId: {SCID}\n    maxFrameLength: {max}\n    errorDetection: CRC16\n    \
         # Uplink SDLS: AES-256-GCM, the IV is the anti-replay counter (Yamcs persists it).\n    encryption:\n",
        host = r.tc_host,
        port = r.tc_port,
        max = tc_frame::MAX_LEN,
    );
    sdls_sa(y, tc_spi, &tc_key_file(n, tc_spi), "");
    let _ = write!(
        y,
        "    virtualChannels:\n      - vcId: {vc}\n        service: PACKET\n        encryptionSpi: {tc_spi}\n        \
         stream: tc_robot_{n}\n{post}        \
         # COP-1: FOP-1 driven by the CLCW of the TM frames (mib::link::cop1).\n        useCop1: true\n        \
         clcwStream: clcw_robot_{n}\n        cop1T1: {t1_s}\n        cop1TxLimit: {tx}\n        \
         slidingWindowWidth: {k}\n        initialClcwWait: {wait}\n",
        vc = tc_vc::COMMAND,
        post = pus_postprocessor("        "),
        tx = cop1::FOP_TX_LIMIT,
        k = cop1::FOP_SLIDING_WINDOW,
        wait = cop1::FOP_INITIAL_CLCW_WAIT_S,
    );
    let _ = write!(
        y,
        "  - name: tm_robot_{n}\n    class: org.yamcs.tctm.ccsds.UdpTmFrameLink\n    port: {port}\n    frameType: TM\n    \
         spacecraftId: {SCID}\n    frameLength: {len}\n    errorDetection: CRC16\n    \
         clcwStream: clcw_robot_{n}\n    \
         # Downlink SDLS: a key of its own; anti-replay on, window = the on-board reserve rule.\n    encryption:\n",
        port = r.tm_port,
        len = tm_frame::LEN,
    );
    sdls_sa(
        y,
        tm_spi,
        &tm_key_file(n, tm_spi),
        &format!(
            "          verifySeqNum: true\n          seqNumWindow: {}\n",
            sdls::ANTI_REPLAY_WINDOW
        ),
    );
    let _ = write!(
        y,
        "    virtualChannels:\n      - vcId: {rt}\n        ocfPresent: true\n        service: PACKET\n        \
         encryptionSpis: [{tm_spi}]\n        maxPacketLength: {max}\n        stream: tm_robot_{n}\n{pre}      \
         - vcId: {rp}\n        ocfPresent: true\n        service: PACKET\n        encryptionSpis: [{tm_spi}]\n        \
         maxPacketLength: {max}\n        stream: tm_robot_{n}\n{pre}      \
         # CFDP PDU packets: no PUS header, no packet CRC (the frame has its CRC and MAC), so not\n      \
         # the PUS preprocessor (it drops them); to the CFDP service through {files} and etc/cfdp.sql.\n      \
         - vcId: {fv}\n        ocfPresent: true\n        service: PACKET\n        encryptionSpis: [{tm_spi}]\n        \
         maxPacketLength: {max}\n        stream: {files}\n        \
         packetPreprocessorClassName: org.yamcs.tctm.GenericPacketPreprocessor\n        packetPreprocessorArgs:\n          \
         timestampOffset: -1\n          seqCountOffset: 0\n      \
         # Idle frames in clear: only their CLCW is used.\n      - vcId: {idle}\n        ocfPresent: true\n        \
         service: PACKET\n        maxPacketLength: {max}\n        stream: tm_robot_{n}\n{pre}",
        rt = tm_vc::REALTIME,
        rp = tm_vc::REPLAY,
        fv = tm_vc::FILES,
        files = files_stream(n),
        idle = tm_vc::IDLE,
        max = config::MAX_PACKET_LEN.max(tm_frame::SECURE_DATA_LEN),
        pre = pus_preprocessor("        "),
    );
}

// ---------------------------------------------------------------------------
// File transfer: Yamcs' CFDP service (`org.yamcs.cfdp.CfdpService`) as the ground entity,
// `mib::cfdp` for every number (docs/files.md, "Yamcs").

/// Name of the CFDP service (the file-transfer service of Yamcs' API and web UI).
pub const CFDP_SERVICE: &str = "cfdp";
/// Bucket the operator uploads from: the folder [`UPLOAD_DIR`] of the instance directory.
pub const UPLOAD_BUCKET: &str = "cfdpUp";
pub const UPLOAD_DIR: &str = "files/up";
/// Bucket the files from the robots arrive in: the folder [`DOWNLOAD_DIR`].
pub const DOWNLOAD_BUCKET: &str = "cfdpDown";
pub const DOWNLOAD_DIR: &str = "files/down";
/// Name of Yamcs' own entity (ID `mib::cfdp::GROUND_ENTITY_ID`).
pub const GROUND_ENTITY: &str = "ground";
/// The stream SQL that carries PDUs between the frame links and the CFDP service.
pub const CFDP_SQL_FILE: &str = "etc/cfdp.sql";
/// Time between two PDUs Yamcs sends: one per on-board control period, about 95 KB/s of
/// file data, under what COP-1's window carries (`docs/files.md`, "Measured"); the FOP
/// queues what its window cannot take yet, so the pace only keeps that queue short.
pub const PDU_DELAY_MS: u32 = mib::config::CONTROL_PERIOD_MS;

/// Name of robot `n`'s remote entity in Yamcs.
pub fn robot_entity(n: u8) -> String {
    format!("robot-{n}")
}

/// Yamcs stream of robot `n`'s CFDP PDU packets (the TM frame link's files VC).
pub fn files_stream(n: u8) -> String {
    format!("files_robot_{n}")
}

/// First two bytes of a CFDP PDU packet's primary header: version 0, type (TM 0 / TC 1), no
/// secondary header, `mib::cfdp::APID`.
fn pdu_packet_word(tc: bool) -> u16 {
    (u16::from(tc) << 12) | mib::cfdp::APID
}

/// The CFDP service: Yamcs is the ground entity, each robot a remote entity; PDU sizes,
/// entity ID and sequence number lengths, checksum, timers and limits from `mib::cfdp`.
fn cfdp_service(y: &mut String, s: &YamcsSetup) {
    use mib::cfdp as c;
    let _ = write!(
        y,
        "  # Files (docs/files.md): CFDP class 1 and 2 with each robot's entity, PDUs in space packets\n  \
         # on APID {apid:#05x} over the frame links (COP-1 up, SDLS both ways; etc/cfdp.sql).\n  \
         - class: org.yamcs.cfdp.CfdpService\n    name: {CFDP_SERVICE}\n    args:\n      \
         inStream: cfdp_in\n      outStream: cfdp_out\n      incomingBucket: {DOWNLOAD_BUCKET}\n      \
         entityIdLength: {eid}\n      sequenceNrLength: {seq}\n      maxPduSize: {pdu}\n      \
         checksumType: MODULAR\n      sleepBetweenPdus: {PDU_DELAY_MS}\n      \
         eofAckTimeout: {ack}\n      eofAckLimit: {ackl}\n      finAckTimeout: {ack}\n      finAckLimit: {ackl}\n      \
         nakTimeout: {nak}\n      nakLimit: {nakl}\n      inactivityTimeout: {inact}\n      \
         # One transaction each way at a time on board: Yamcs queues the next upload.\n      \
         maxNumPendingUploads: 1\n      queueConcurrentUploads: true\n      \
         # The robots' directory listing is a file named {listing} (see docs/files.md); Yamcs asks\n      \
         # for a listing under a name the robot's store refuses, so the listing is not offered.\n      \
         hasFileListingCapability: false\n      \
         localEntities:\n        - name: {GROUND_ENTITY}\n          id: {ground}\n      remoteEntities:\n",
        apid = c::APID,
        eid = c::ENTITY_ID_LEN,
        seq = c::SEQ_NUM_LEN,
        pdu = c::MAX_PDU_LEN,
        ack = c::YAMCS_ACK_TIMER_MS,
        ackl = c::YAMCS_ACK_LIMIT,
        nak = c::YAMCS_NAK_TIMER_MS,
        nakl = c::YAMCS_NAK_LIMIT,
        inact = c::INACTIVITY_MS,
        listing = c::LISTING_NAME,
        ground = c::GROUND_ENTITY_ID,
    );
    for r in &s.robots {
        let _ = write!(
            y,
            "        - name: {}\n          id: {}\n",
            robot_entity(r.robot),
            c::robot_entity_id(r.robot)
        );
    }
}

/// The stream SQL of the CFDP service (`streamConfig.sqlFile`): PDUs from each robot's files
/// VC into `cfdp_in` (the packet's data field), and each PDU of `cfdp_out` to its robot's TC
/// stream in a TC packet on the CFDP APID (the PUS post-processor writes the length and
/// sequence count; without a secondary header it adds no CRC). A PDU belongs to robot N when
/// N started its transaction (`entityId`, the initiator) or, in a transaction Yamcs
/// started, when N is the PDU header's destination entity (after the fixed 4 bytes, the
/// source ID and the sequence number).
fn cfdp_sql(s: &YamcsSetup) -> String {
    use mib::cfdp as c;
    let dest_at = 4 + c::ENTITY_ID_LEN + c::SEQ_NUM_LEN;
    let mut q = String::from(
        "-- Generated from the MMIC-I MIB: CFDP PDUs between the frame links and the CFDP service.\n\
         create stream cfdp_in (pdu BINARY)\n\
         create stream cfdp_out (gentime TIMESTAMP, entityId LONG, seqNum INT, pdu BINARY)\n",
    );
    for r in &s.robots {
        let id = c::robot_entity_id(r.robot);
        let _ = write!(
            q,
            "insert into cfdp_in select substring(packet, 6) as pdu from {files} \
             where extract_short(packet, 0) = {tm_word}\n\
             insert into tc_robot_{n} select gentime, 'cfdp-service' as origin, seqNum, \
             '/yamcs/cfdp/upload' as cmdName, unhex('{tc_word:04X}C0000000') + pdu as binary from cfdp_out \
             where entityId = {id} or (entityId = {ground} and extract_short(pdu, {dest_at}) = {id})\n",
            files = files_stream(r.robot),
            tm_word = pdu_packet_word(false),
            n = r.robot,
            tc_word = pdu_packet_word(true),
            ground = c::GROUND_ENTITY_ID,
        );
    }
    q
}

const PROCESSOR_YAML: &str = "# Generated from the MMIC-I MIB: Yamcs processors.\n\
realtime:\n  services:\n    - class: org.yamcs.StreamTmPacketProvider\n    - class: org.yamcs.StreamTcCommandReleaser\n    \
- class: org.yamcs.tctm.StreamParameterProvider\n    - class: org.yamcs.algorithms.AlgorithmManager\n    \
- class: org.yamcs.parameter.LocalParameterManager\n  config:\n    generateEvents: true\n    subscribeAll: true\n    \
alarm:\n      parameterCheck: true\n      parameterServer: enabled\n      eventServer: enabled\n    \
tmProcessor:\n      ignoreOutOfContainerEntries: false\n    recordInitialValues: true\n    recordLocalValues: true\n\
Archive:\n  services:\n    - class: org.yamcs.tctm.ReplayService\n    - class: org.yamcs.algorithms.AlgorithmManager\n\
ParameterArchive:\n  services:\n    - class: org.yamcs.tctm.ReplayService\n    - class: org.yamcs.algorithms.AlgorithmManager\n\
ArchiveRetrieval:\n  config:\n    subscribeContainerArchivePartitions: false\n  services:\n    \
- class: org.yamcs.tctm.ReplayService\n    - class: org.yamcs.algorithms.AlgorithmManager\n";

/// Template of event `e` for `PusEventDecoder`: the description, then every parameter
/// (engineering value: names for enumerated ones).
pub fn event_template(e: &mib::events::EventDef) -> String {
    let mut t = e.desc.replace(['{', '}'], "");
    for p in e.params {
        let _ = write!(t, "; {}={{{}}}", p.name, xtce::event_param_name(e, p.name));
    }
    t
}

/// Name of the MDB parameter of event parameter `p` of `e` (as in the generic XTCE).
pub fn event_param(e: &EventDef, p: &str) -> String {
    xtce::event_param_name(e, p)
}

/// The event templates of `robots` (JSON list of `eventId` and `template`). The key is
/// `<EVENT_ID label>-<APID>`, which `PusEventDecoder` looks up before the bare label, so
/// each robot's events say which robot they come from.
pub fn events_json(robots: &[u8]) -> String {
    let list: Vec<serde_json::Value> = robots
        .iter()
        .filter_map(|&n| apid::robot_apid(n).map(|a| (n, a)))
        .flat_map(|(n, a)| {
            EVENTS.iter().map(move |e| {
                serde_json::json!({
                    "eventId": format!("{}-{a}", e.name),
                    "template": format!("robot {n}: {}", event_template(e)),
                })
            })
        })
        .collect();
    serde_json::to_string_pretty(&list).unwrap_or_else(|_| "[]".into())
}

// ---------------------------------------------------------------------------
// Additions to the XTCE (called by the XTCE exporter in the Yamcs flavour).

/// Days from 1958-01-01 to 1970-01-01, in seconds (offset of `TM_TIME_DAYS`).
const CDS_EPOCH_OFFSET_S: i64 = -mib::headers::CCSDS_TO_UNIX_DAYS * 86_400;

/// Types of the TM header fields that differ in the Yamcs flavour; false if `f` is not one.
fn header_type(x: &mut Xml, f: &HeaderField) -> bool {
    match f.name {
        "TM_TIME_DAYS" => {
            x.open(&format!(
                "<xtce:AbsoluteTimeParameterType name=\"TM_TIME_DAYS_Type\" shortDescription=\"{}: start of the on-board day (UTC)\">",
                esc(f.desc)
            ));
            x.open(&format!(
                "<xtce:Encoding units=\"seconds\" offset=\"{CDS_EPOCH_OFFSET_S}\" scale=\"86400\">"
            ));
            x.line(&format!(
                "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
                f.bits
            ));
            x.close("</xtce:Encoding>");
            x.open("<xtce:ReferenceTime>");
            x.line("<xtce:Epoch>UNIX</xtce:Epoch>");
            x.close("</xtce:ReferenceTime>");
            x.close("</xtce:AbsoluteTimeParameterType>");
            true
        }
        "TM_TIME_MS" => {
            x.open(&format!(
                "<xtce:AbsoluteTimeParameterType name=\"TM_TIME_MS_Type\" shortDescription=\"{}: with TM_TIME_DAYS, the on-board time of the packet (UTC)\">",
                esc(f.desc)
            ));
            x.open("<xtce:Encoding units=\"seconds\" scale=\"0.001\">");
            x.line(&format!(
                "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
                f.bits
            ));
            x.close("</xtce:Encoding>");
            x.open("<xtce:ReferenceTime>");
            x.line("<xtce:OffsetFrom parameterRef=\"TM_TIME_DAYS\"/>");
            x.close("</xtce:ReferenceTime>");
            x.close("</xtce:AbsoluteTimeParameterType>");
            true
        }
        _ => false,
    }
}

/// `HK_SID` and `EVENT_ID` as enumerations (`PusEventDecoder` needs an enumerated ID).
fn id_types(x: &mut Xml) {
    enumerated_type(
        x,
        "HK_SID_Type",
        &Field::new("HK_SID", PType::U16, "housekeeping structure ID").names(Names::Sid),
    );
    enumerated_type(
        x,
        "EVENT_ID_Type",
        &Field::new("EVENT_ID", PType::U16, "event ID").names(Names::Event),
    );
}

fn verification_param(f: &Field) -> String {
    format!("{VERIFICATION}_request_id_{}", f.name)
}

/// Types of the shared request-ID parameters.
fn extra_types(x: &mut Xml) {
    for f in REQUEST_ID.fields {
        x.open(&format!(
            "<xtce:IntegerParameterType name=\"{}_Type\" shortDescription=\"{}\" signed=\"false\" sizeInBits=\"32\">",
            verification_param(f),
            esc(f.desc)
        ));
        x.line("<xtce:UnitSet/>");
        x.line(&format!(
            "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
            f.bits
        ));
        x.close("</xtce:IntegerParameterType>");
    }
    x.open(&format!(
        "<xtce:IntegerParameterType name=\"{VERIFICATION_SUBTYPE}_Type\" shortDescription=\"TM[1,x] subtype (read again by the shared container)\" signed=\"false\" sizeInBits=\"32\">"
    ));
    x.line("<xtce:UnitSet/>");
    x.line("<xtce:IntegerDataEncoding sizeInBits=\"8\" encoding=\"unsigned\"/>");
    x.close("</xtce:IntegerParameterType>");
}

fn extra_params(x: &mut Xml) {
    for f in REQUEST_ID.fields {
        let n = verification_param(f);
        parameter(x, &n, &format!("{n}_Type"), &format!("{} (every TM[1,x])", f.desc), &[]);
    }
    for (_, stage, sub, _) in STAGES {
        for f in REQUEST_ID.fields {
            parameter(
                x,
                &stage_param(stage, f.name),
                &format!("{}_Type", verification_param(f)),
                &format!("{} (TM[1,{sub}] and TM[1,{}] only)", f.desc, sub + 1),
                &[],
            );
        }
        parameter(
            x,
            &stage_param(stage, "subtype"),
            &format!("{VERIFICATION_SUBTYPE}_Type"),
            &format!("subtype of the last TM[1,{sub}] or TM[1,{}]", sub + 1),
            &[],
        );
    }
    parameter(
        x,
        VERIFICATION_SUBTYPE,
        &format!("{VERIFICATION_SUBTYPE}_Type"),
        "subtype of the last TM[1,x] (stage and outcome of the verification)",
        &[],
    );
}

/// The TM[1,x] subtype as a parameter of its own, set only by TM[1,x]: the verifiers'
/// request ID, subtype and failure code then always come from the same report
/// (`TM_SUBSERVICE` is set by every packet).
pub const VERIFICATION_SUBTYPE: &str = "VERIFICATION_subtype";

/// Bit offset of `TM_SUBSERVICE` from the start of a TM packet.
fn subservice_bit_offset() -> u32 {
    let primary: u32 = HEADER_PRIMARY.iter().map(|f| f.bits).sum();
    let before: u32 = HEADER_TM_SEC
        .iter()
        .take_while(|f| f.name != "TM_SUBSERVICE")
        .map(|f| f.bits)
        .sum();
    primary + before
}

/// The container every TM[1,x] matches besides its own: the request ID under one set of
/// names, for the verifiers.
fn extra_containers(x: &mut Xml) {
    x.open(&format!(
        "<xtce:SequenceContainer name=\"{VERIFICATION}_REPORT\" shortDescription=\"TM[1,x] request verification report: the request ID and the subtype, shared by every subtype (Yamcs command verifiers)\">"
    ));
    x.open("<xtce:EntryList>");
    for f in REQUEST_ID.fields {
        x.line(&format!(
            "<xtce:ParameterRefEntry parameterRef=\"{}\"/>",
            verification_param(f)
        ));
    }
    // The subtype again, from its place in the secondary header.
    x.open(&format!(
        "<xtce:ParameterRefEntry parameterRef=\"{VERIFICATION_SUBTYPE}\">"
    ));
    x.open("<xtce:LocationInContainerInBits referenceLocation=\"containerStart\">");
    x.line(&format!(
        "<xtce:FixedValue>{}</xtce:FixedValue>",
        subservice_bit_offset()
    ));
    x.close("</xtce:LocationInContainerInBits>");
    x.close("</xtce:ParameterRefEntry>");
    x.close("</xtce:EntryList>");
    x.open("<xtce:BaseContainer containerRef=\"PUS_TM\">");
    x.open("<xtce:RestrictionCriteria>");
    x.open("<xtce:ComparisonList>");
    x.line(&format!(
        "<xtce:Comparison parameterRef=\"{}\" value=\"{}\" useCalibratedValue=\"false\"/>",
        mib::headers::TM_SERVICE,
        mib::tc::service::VERIFICATION
    ));
    x.close("</xtce:ComparisonList>");
    x.close("</xtce:RestrictionCriteria>");
    x.close("</xtce:BaseContainer>");
    x.close("</xtce:SequenceContainer>");
    // Per verification stage: the request ID and subtype of that stage's reports only, so
    // that a verifier judges its own stage's last report whenever it runs (a TM[1,1]
    // that arrives before the sequence count reaches the command history is still judged
    // when the count comes, even if the TM[1,3] and TM[1,7] came in between).
    for (_, stage, sub, _) in STAGES {
        for s in [sub, sub + 1] {
            x.open(&format!(
                "<xtce:SequenceContainer name=\"{VERIFICATION}_REPORT_{s}\" shortDescription=\"TM[1,{s}]: request ID and subtype for the {stage} verifier\">"
            ));
            x.open("<xtce:EntryList>");
            for f in REQUEST_ID.fields {
                x.line(&format!(
                    "<xtce:ParameterRefEntry parameterRef=\"{}\"/>",
                    stage_param(stage, f.name)
                ));
            }
            x.open(&format!(
                "<xtce:ParameterRefEntry parameterRef=\"{}\">",
                stage_param(stage, "subtype")
            ));
            x.open("<xtce:LocationInContainerInBits referenceLocation=\"containerStart\">");
            x.line(&format!(
                "<xtce:FixedValue>{}</xtce:FixedValue>",
                subservice_bit_offset()
            ));
            x.close("</xtce:LocationInContainerInBits>");
            x.close("</xtce:ParameterRefEntry>");
            x.close("</xtce:EntryList>");
            x.open("<xtce:BaseContainer containerRef=\"PUS_TM\">");
            x.open("<xtce:RestrictionCriteria>");
            x.open("<xtce:ComparisonList>");
            x.line(&format!(
                "<xtce:Comparison parameterRef=\"{}\" value=\"{}\" useCalibratedValue=\"false\"/>",
                mib::headers::TM_SERVICE,
                mib::tc::service::VERIFICATION
            ));
            x.line(&format!(
                "<xtce:Comparison parameterRef=\"TM_SUBSERVICE\" value=\"{s}\" useCalibratedValue=\"false\"/>"
            ));
            x.close("</xtce:ComparisonList>");
            x.close("</xtce:RestrictionCriteria>");
            x.close("</xtce:BaseContainer>");
            x.close("</xtce:SequenceContainer>");
        }
    }
}

/// The verification stages: XTCE verifier kind, Yamcs stage name, success subtype (the
/// failure subtype is the next), check window (s after release).
const STAGES: [(&str, &str, u8, u32); 3] = [
    ("Accepted", "Acceptance", 1, ACCEPTANCE_WINDOW_S),
    ("Execution", "Start", 3, START_WINDOW_S),
    ("Complete", "Completion", 7, COMPLETION_WINDOW_S),
];

/// A parameter of the TM header that every TM packet sets: an input of every command
/// verifier, so that each is judged again on every packet (REV-ANOM-16).
pub const EVERY_TM_TRIGGER: &str = mib::headers::TM_SERVICE;

/// A parameter of stage `stage`'s own request-ID container (`VERIFICATION_ACCEPTANCE_apid`).
pub fn stage_param(stage: &str, field: &str) -> String {
    format!("{VERIFICATION}_{}_{field}", stage.to_ascii_uppercase())
}

/// Value of a TC header field that is no operator argument in the Yamcs flavour (written
/// as 0, filled in by `PusCommandPostprocessor`).
fn tc_header_fixed(f: &HeaderField) -> Option<u32> {
    match f.name {
        "SRC_SEQ_CTR" | "PKT_LEN" => Some(0),
        _ => None,
    }
}

/// Name of the TM[1,x] failure report of stage `sub` (its failure code parameter is
/// `<name>_failure_code`).
fn failure_report(sub: u8) -> &'static str {
    TMS.iter()
        .find(|t| t.service == mib::tc::service::VERIFICATION && t.subservice == sub + 1)
        .map_or("?", |t| t.name)
}

/// Command verifiers of the abstract `PUS_TC` (inherited by every command).
fn verifiers(x: &mut Xml) {
    x.open("<xtce:VerifierSet>");
    for (kind, stage, sub, window) in STAGES {
        let code = format!("{}_failure_code", failure_report(sub));
        x.open(&format!("<xtce:{kind}Verifier name=\"{stage}\">"));
        x.open(&format!(
            "<xtce:CustomAlgorithm name=\"PUS1_{}\" shortDescription=\"TM[1,{sub}] / TM[1,{}] for this command\">",
            stage.to_ascii_uppercase(),
            sub + 1
        ));
        x.line(&format!(
            "<xtce:AlgorithmText language=\"Java\">org.yamcs.pus.Pus1Verifier({{stage: {sub}, template: \"{{code}}\"}})</xtce:AlgorithmText>"
        ));
        x.open("<xtce:InputSet>");
        let (apid, seq, subtype) = (
            stage_param(stage, "apid"),
            stage_param(stage, "seq_count"),
            stage_param(stage, "subtype"),
        );
        for (p, n) in [
            ("/yamcs/cmd/arg/PKT_APID", "sentApid"),
            ("/yamcs/cmdHist/ccsds-seqcount", "sentSeq"),
            (apid.as_str(), "rcvdApid"),
            (seq.as_str(), "rcvdSeq"),
            (subtype.as_str(), "subtype"),
            (code.as_str(), "code"),
            // Read by no one: an input set by every TM packet, so that the verifier is
            // judged again on the next packet (REV-ANOM-16, see below).
            (EVERY_TM_TRIGGER, "everyTm"),
        ] {
            x.line(&format!(
                "<xtce:InputParameterInstanceRef parameterRef=\"{p}\" inputName=\"{n}\"/>"
            ));
        }
        x.close("</xtce:InputSet>");
        // No trigger set: a verifier runs when one of its inputs changes, i.e. on a
        // report of its stage (request ID, subtype and code all from that report), when
        // the sent sequence count reaches the command history (the stage's last report,
        // if it came first, is then judged), and on every TM packet (`everyTm`). The last
        // is for a race in Yamcs 5.12.8 (REV-ANOM-16): any command-history update of the
        // command (COP-1's acknowledgement of the TC frame, on its own thread, comes with
        // the CLCW of the TM frame that carries the TM[1,1]) refreshes the verifier's
        // inputs from the processor's last-value cache, which Yamcs updates only after the
        // whole packet has been processed; landing between the TM thread's input update
        // and its run of the algorithm, it puts the previous report's request ID back and
        // the report is not recognised. Nothing of that stage follows, so the stage stayed
        // pending until the completion cancelled it. On the next packet the cache holds
        // the report and the verifier judges it.
        x.close("</xtce:CustomAlgorithm>");
        x.line(&format!(
            "<xtce:CheckWindow timeToStopChecking=\"PT{window}S\" timeWindowIsRelativeTo=\"commandRelease\"/>"
        ));
        x.close(&format!("</xtce:{kind}Verifier>"));
    }
    x.close("</xtce:VerifierSet>");
}

// --- Mode names per node kind -------------------------------------------------------

/// Sub-space system of the robot's MDB with the module-named variants of the mode fields
/// of events (same short names, so the event templates need no change).
pub const MODULE_MODES: &str = "MODULE_MODES";

fn mode_enum_type(x: &mut Xml, tname: &str, f: &Field, kind: NodeKind) {
    x.open(&format!(
        "<xtce:EnumeratedParameterType name=\"{}\" shortDescription=\"{} ({} modes)\">",
        esc(tname),
        esc(f.desc),
        if kind == NodeKind::Root { "robot" } else { "module" }
    ));
    x.line("<xtce:UnitSet/>");
    x.line(&format!(
        "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"unsigned\"/>",
        f.bits
    ));
    x.open("<xtce:EnumerationList>");
    for m in 0..=u8::MAX as u32 {
        if let Some(n) = mib::modes::mode_name(kind, m) {
            x.line(&format!("<xtce:Enumeration value=\"{m}\" label=\"{n}\"/>"));
        }
    }
    x.close("</xtce:EnumerationList>");
    x.close("</xtce:EnumeratedParameterType>");
}

/// An event whose mode fields are named by its `node` field (its first parameter).
fn mode_split(e: &EventDef) -> bool {
    e.params.first().is_some_and(|p| p.names == Names::Node) && e.params.iter().any(|p| p.names == Names::Mode)
}

/// Type of an event's mode field in the robot's space system: the robot's mode names
/// (the module-named variant is in [`MODULE_MODES`]); false for any other field.
fn robot_mode_type(x: &mut Xml, tname: &str, f: &Field) -> bool {
    if f.names != Names::Mode {
        return false;
    }
    mode_enum_type(x, tname, f, NodeKind::Root);
    true
}

/// Containers of an event with mode fields: the event container holds the node; one child
/// for the robot node (robot mode names), one for every other node (module mode names).
/// False for an event without mode fields.
fn mode_event_containers(x: &mut Xml, e: &EventDef, severity_container: &str, robot: u8) -> bool {
    if !mode_split(e) {
        return false;
    }
    let name = format!("EVT_{}", e.name);
    let node = xtce::event_param_name(e, e.params[0].name);
    xtce::container(
        x,
        &name,
        &format!("event 0x{:04X}: {}", e.id, e.desc),
        false,
        std::slice::from_ref(&node),
        Some((severity_container, &[("EVENT_ID", e.id.to_string())])),
    );
    let rest: Vec<(String, bool)> = e.params[1..]
        .iter()
        .map(|p| (xtce::event_param_name(e, p.name), p.names == Names::Mode))
        .collect();
    node_children(x, &name, &node, &rest, e.name, robot);
    true
}

/// The fields of a TM body whose mode fields are named by its `node` field (the first),
/// if it is one: plain fields only.
fn mode_tm_fields(t: &TmDef) -> Option<Vec<Field>> {
    let fields: Vec<Field> = t
        .body
        .iter()
        .map(|i| match i {
            Item::Field(f) => Some(*f),
            Item::Sub { .. } | Item::Group { .. } | Item::Packet { .. } | Item::Tail(_) => None,
        })
        .collect::<Option<_>>()?;
    (fields.first().is_some_and(|f| f.names == Names::Node) && fields.iter().any(|f| f.names == Names::Mode))
        .then_some(fields)
}

/// Label of a value the MIB does not name, in an [`open_enumerated_type`].
pub const UNNAMED_VALUE: &str = "UNNAMED_VALUE";

/// An enumerated type that decodes whatever the value: the MIB's names,
/// and every other value of the field's width as [`UNNAMED_VALUE`] (one enumeration
/// range; Yamcs looks the exact values up before the ranges). For fields that carry a
/// failure code, which an operator reads by name but which may hold a code the MIB
/// does not know.
fn open_enumerated_type(x: &mut Xml, tname: &str, f: &Field) {
    enumerated_type(x, tname, f);
    let close = "</xtce:EnumerationList>";
    let Some(i) = x.s.rfind(close) else { return };
    let line = x.s[..i].rfind('\n').map_or(0, |j| j + 1);
    let indent = x.s[line..i].to_string();
    let (lo, hi) = if f.ptype.signed() {
        (-(1i64 << (f.bits - 1)), (1i64 << (f.bits - 1)) - 1)
    } else {
        (0, (1i64 << f.bits) - 1)
    };
    x.s.insert_str(
        line,
        &format!("{indent}  <xtce:Enumeration value=\"{lo}\" maxValue=\"{hi}\" label=\"{UNNAMED_VALUE}\"/>\n"),
    );
}

/// Containers, types and parameters of a TM whose mode fields depend on its node (TM[200,6]
/// and [200,7]), split like the events ([`mode_event_containers`]); false for any other TM.
fn mode_tm(t: &TmDef, types: &mut Xml, params: &mut Xml, containers: &mut Xml, robot: u8) -> bool {
    let Some(fields) = mode_tm_fields(t) else {
        return false;
    };
    for f in &fields {
        let n = format!("{}_{}", t.name, f.name);
        let tname = format!("{n}_Type");
        if f.names == Names::Mode {
            mode_enum_type(types, &tname, f, NodeKind::Root);
        } else if f.names == Names::FailureCode {
            open_enumerated_type(types, &tname, f);
        } else if !f.names.is_none() {
            enumerated_type(types, &tname, f);
        } else {
            types.open(&format!(
                "<xtce:IntegerParameterType name=\"{}\" shortDescription=\"{}\" signed=\"{}\" sizeInBits=\"32\">",
                esc(&tname),
                esc(f.desc),
                f.ptype.signed()
            ));
            types.line("<xtce:UnitSet/>");
            types.line(&format!(
                "<xtce:IntegerDataEncoding sizeInBits=\"{}\" encoding=\"{}\"/>",
                f.bits,
                if f.ptype.signed() { "twosComplement" } else { "unsigned" }
            ));
            types.close("</xtce:IntegerParameterType>");
        }
        parameter(params, &n, &tname, f.desc, &[]);
    }
    let name = format!("TM_{}", t.name);
    let node = format!("{}_{}", t.name, fields[0].name);
    xtce::container(
        containers,
        &name,
        &format!("TM[{},{}] {}", t.service, t.subservice, t.desc),
        false,
        std::slice::from_ref(&node),
        Some((
            "PUS_TM",
            &[
                (mib::headers::TM_SERVICE, t.service.to_string()),
                ("TM_SUBSERVICE", t.subservice.to_string()),
            ],
        )),
    );
    let rest: Vec<(String, bool)> = fields[1..]
        .iter()
        .map(|f| (format!("{}_{}", t.name, f.name), f.names == Names::Mode))
        .collect();
    node_children(containers, &name, &node, &rest, t.name, robot);
    true
}

/// The robot-node and module-node children of container `name`, restricted on `node`;
/// `rest` lists the parameters after the node and whether each is a mode field.
fn node_children(x: &mut Xml, name: &str, node: &str, rest: &[(String, bool)], what: &str, robot: u8) {
    for (suffix, op, module) in [("ROBOT", "==", false), ("MODULE", "!=", true)] {
        x.open(&format!(
            "<xtce:SequenceContainer name=\"{name}_{suffix}\" shortDescription=\"{what} of the {} node{}\">",
            suffix.to_ascii_lowercase(),
            if module {
                "s (module mode names)"
            } else {
                " (robot mode names)"
            }
        ));
        x.open("<xtce:EntryList>");
        for (n, is_mode) in rest {
            // Absolute: Yamcs 5.12.8 resolves "MODULE_MODES/NAME" to the NAME of the
            // enclosing space system (measured: the module child then read the
            // robot-named parameter).
            let r = if module && *is_mode {
                format!("/MMIC_I_ROBOT_{robot}/{MODULE_MODES}/{n}")
            } else {
                n.clone()
            };
            x.line(&format!("<xtce:ParameterRefEntry parameterRef=\"{}\"/>", esc(&r)));
        }
        x.line("<xtce:ParameterRefEntry parameterRef=\"PEC\"/>");
        x.close("</xtce:EntryList>");
        x.open(&format!("<xtce:BaseContainer containerRef=\"{name}\">"));
        x.open("<xtce:RestrictionCriteria>");
        x.open("<xtce:ComparisonList>");
        x.line(&format!(
            "<xtce:Comparison parameterRef=\"{node}\" comparisonOperator=\"{}\" value=\"{}\" useCalibratedValue=\"false\"/>",
            esc(op),
            mib::modes::node::ROBOT
        ));
        x.close("</xtce:ComparisonList>");
        x.close("</xtce:RestrictionCriteria>");
        x.close("</xtce:BaseContainer>");
        x.close("</xtce:SequenceContainer>");
    }
}

/// The module-named variants of every mode field: (parameter name, field).
fn module_mode_fields() -> Vec<(String, Field)> {
    let mut out: Vec<(String, Field)> = EVENTS
        .iter()
        .filter(|e| mode_split(e))
        .flat_map(|e| {
            e.params
                .iter()
                .filter(|p| p.names == Names::Mode)
                .map(move |p| (xtce::event_param_name(e, p.name), *p))
        })
        .collect();
    for t in TMS {
        if let Some(fields) = mode_tm_fields(t) {
            out.extend(
                fields
                    .into_iter()
                    .filter(|f| f.names == Names::Mode)
                    .map(|f| (format!("{}_{}", t.name, f.name), f)),
            );
        }
    }
    out
}

/// The [`MODULE_MODES`] space system (written last in the robot's space system).
fn module_modes_space_system(x: &mut Xml) {
    x.open(&format!(
        "<xtce:SpaceSystem name=\"{MODULE_MODES}\" shortDescription=\"Mode fields of events and reports about module nodes, with the module mode names\">"
    ));
    x.open("<xtce:TelemetryMetaData>");
    let fields = module_mode_fields();
    x.open("<xtce:ParameterTypeSet>");
    for (n, f) in &fields {
        mode_enum_type(x, &format!("{n}_Type"), f, NodeKind::Arm);
    }
    x.close("</xtce:ParameterTypeSet>");
    x.open("<xtce:ParameterSet>");
    for (n, f) in &fields {
        parameter(x, n, &format!("{n}_Type"), f.desc, &[]);
    }
    x.close("</xtce:ParameterSet>");
    x.close("</xtce:TelemetryMetaData>");
    x.close("</xtce:SpaceSystem>");
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: YAMCS-EXPORT-01
    #[test]
    fn robot_sets_parse_lists_and_ranges() {
        let s: RobotSet = "1-3, 7".parse().unwrap();
        assert_eq!(s.iter().collect::<Vec<_>>(), [1, 2, 3, 7]);
        assert!("0".parse::<RobotSet>().is_err());
        assert!("255".parse::<RobotSet>().is_err());
        assert!("3-1".parse::<RobotSet>().is_err());
        assert!("".parse::<RobotSet>().is_err());
        assert_eq!(RobotSet::one(0).iter().collect::<Vec<_>>(), [apid::DEFAULT_ROBOT]);
        assert_eq!("254".parse::<RobotSet>().unwrap().iter().collect::<Vec<_>>(), [254]);
    }

    // verifies: YAMCS-EXPORT-01
    #[test]
    fn lab_instance_has_packet_links_mdb_and_decoder_per_robot() {
        let setup = YamcsSetup::with_links("2,5".parse().unwrap(), Links::LabPackets);
        let files = yamcs_instance(&setup);
        let get = |n: &str| &files.iter().find(|(p, _)| p == n).unwrap().1;
        let inst = get("etc/yamcs.mmic.yaml");
        assert!(inst.contains("LAB ONLY"));
        for n in [2u8, 5] {
            assert!(inst.contains(&format!("port: {}", TM_BASE_PORT + n as u16)));
            assert!(inst.contains(&format!("port: {}", mib::host_config::robot_port(n))));
            assert!(inst.contains(&format!("eventIdParameter: /MMIC_I_ROBOT_{n}/EVENT_ID")));
            assert!(get(&mdb_file(n)).contains(&format!("value=\"{}\"", 0x100 + n as u16)));
        }
        assert!(!inst.contains("tm_robot_1"));
        assert!(!inst.contains("ccsds."));
        assert_eq!(inst.matches("CRC-16-CCIIT").count(), 4);
    }

    // verifies: YAMCS-LINK-01
    #[test]
    fn default_instance_has_frame_links_with_cop1_and_sdls_from_the_mib_link() {
        use mib::link::{cop1, sdls, tc_frame, tm_frame, SCID};
        let setup = YamcsSetup::for_robots("2,5".parse().unwrap());
        assert_eq!(setup.links, Links::Frames);
        let files = yamcs_instance(&setup);
        let inst = &files.iter().find(|(p, _)| p == "etc/yamcs.mmic.yaml").unwrap().1;
        assert!(!inst.contains("UdpTmDataLink") && !inst.contains("UdpTcDataLink"));
        assert_eq!(inst.matches("class: org.yamcs.tctm.ccsds.UdpTcFrameLink").count(), 2);
        assert_eq!(inst.matches("class: org.yamcs.tctm.ccsds.UdpTmFrameLink").count(), 2);
        for n in [2u8, 5] {
            assert!(inst.contains(&format!("port: {}", FRAME_BASE_PORT + n as u16)));
            assert!(inst.contains(&format!("port: {}", TM_BASE_PORT + n as u16)));
            assert!(inst.contains(&format!("keyFile: {}", tc_key_file(n, sdls::TC_SPIS[0]))));
            assert!(inst.contains(&format!("keyFile: {}", tm_key_file(n, sdls::TM_SPIS[0]))));
            assert_eq!(inst.matches(&format!("clcwStream: clcw_robot_{n}\n")).count(), 2);
        }
        for want in [
            format!("spacecraftId: {SCID}"),
            format!("maxFrameLength: {}", tc_frame::MAX_LEN),
            format!("frameLength: {}", tm_frame::LEN),
            format!("cop1T1: {}", cop1::FOP_T1_MS / 1000),
            format!("cop1TxLimit: {}", cop1::FOP_TX_LIMIT),
            format!("slidingWindowWidth: {}", cop1::FOP_SLIDING_WINDOW),
            format!("initialClcwWait: {}", cop1::FOP_INITIAL_CLCW_WAIT_S),
            format!("encryptionSpi: {}", sdls::TC_SPIS[0]),
            format!("encryptionSpis: [{}]", sdls::TM_SPIS[0]),
            format!("seqNumWindow: {}", sdls::ANTI_REPLAY_WINDOW),
            "verifySeqNum: true".to_string(),
            "useCop1: true".to_string(),
            format!("pfield: {}", mib::tc::sched_cuc::PFIELD),
            "implicitPfield: true".to_string(),
        ] {
            assert!(inst.contains(&want), "{want}");
        }
        // Pre-processing on VC0, VC1 and VC7 of both robots; post-processing per TC VC.
        assert_eq!(inst.matches("CRC-16-CCIIT").count(), 2 * 4);
    }

    // verifies: YAMCS-FILE-01
    #[test]
    fn the_frame_instance_has_a_cfdp_service_on_the_files_vc_with_the_mibs_numbers() {
        use mib::cfdp as c;
        let setup = YamcsSetup::for_robots("2,5".parse().unwrap());
        let files = yamcs_instance(&setup);
        let get = |n: &str| &files.iter().find(|(p, _)| p == n).unwrap().1;
        let inst = get("etc/yamcs.mmic.yaml");
        for want in [
            "class: org.yamcs.cfdp.CfdpService".to_string(),
            format!("name: {CFDP_SERVICE}"),
            format!("entityIdLength: {}", c::ENTITY_ID_LEN),
            format!("sequenceNrLength: {}", c::SEQ_NUM_LEN),
            format!("maxPduSize: {}", c::MAX_PDU_LEN),
            "checksumType: MODULAR".to_string(),
            format!("eofAckTimeout: {}", c::YAMCS_ACK_TIMER_MS),
            format!("eofAckLimit: {}", c::YAMCS_ACK_LIMIT),
            format!("finAckTimeout: {}", c::YAMCS_ACK_TIMER_MS),
            format!("nakTimeout: {}", c::YAMCS_NAK_TIMER_MS),
            format!("nakLimit: {}", c::YAMCS_NAK_LIMIT),
            format!("inactivityTimeout: {}", c::INACTIVITY_MS),
            format!("incomingBucket: {DOWNLOAD_BUCKET}"),
            format!("- name: {GROUND_ENTITY}\n          id: {}", c::GROUND_ENTITY_ID),
            format!("- name: robot-2\n          id: {}", c::robot_entity_id(2)),
            format!("- name: robot-5\n          id: {}", c::robot_entity_id(5)),
            format!("sqlFile: {CFDP_SQL_FILE}"),
        ] {
            assert!(inst.contains(&want), "{want}");
        }
        // The files VC of each TM frame link: SDLS, no PUS preprocessor, to the files stream.
        for n in [2u8, 5] {
            let vc = format!(
                "- vcId: {}\n        ocfPresent: true\n        service: PACKET\n        encryptionSpis: [{}]\n        \
                 maxPacketLength: {}\n        stream: {}\n        packetPreprocessorClassName: org.yamcs.tctm.GenericPacketPreprocessor\n",
                mib::link::tm_vc::FILES,
                mib::link::sdls::TM_SPIS[0],
                config::MAX_PACKET_LEN.max(mib::link::tm_frame::SECURE_DATA_LEN),
                files_stream(n)
            );
            assert!(inst.contains(&vc), "{vc}");
            assert!(inst.contains(&format!(
                "- name: {}\n      rootContainer: /MMIC_I_ROBOT_{n}/CCSDSPacket",
                files_stream(n)
            )));
        }
        // The PUS preprocessor stays on VC0, VC1 and VC7 only.
        assert_eq!(inst.matches("CRC-16-CCIIT").count(), 2 * 4);
        let sql = get(CFDP_SQL_FILE);
        // TM packet word 0x00F0, TC packet word 0x10F0 + sequence flags "unsegmented".
        assert_eq!(pdu_packet_word(false), c::APID);
        assert_eq!(pdu_packet_word(true), 0x1000 | c::APID);
        for n in [2u16, 5] {
            assert!(sql.contains(&format!(
                "insert into cfdp_in select substring(packet, 6) as pdu from files_robot_{n} where extract_short(packet, 0) = {}\n",
                c::APID
            )));
            assert!(sql.contains(&format!(
                "insert into tc_robot_{n} select gentime, 'cfdp-service' as origin, seqNum, '/yamcs/cfdp/upload' as cmdName, \
                 unhex('{:04X}C0000000') + pdu as binary from cfdp_out where entityId = {n} or (entityId = 0 and extract_short(pdu, 8) = {n})\n",
                0x1000 | c::APID
            )));
        }
        let server = get("etc/yamcs.yaml");
        assert!(server.contains(&format!("- name: {UPLOAD_BUCKET}\n    path: {UPLOAD_DIR}\n")));
        assert!(server.contains(&format!("- name: {DOWNLOAD_BUCKET}\n    path: {DOWNLOAD_DIR}\n")));
        // Nothing unauthenticated moves a file: the lab instance has no file service.
        let lab = yamcs_instance(&YamcsSetup::with_links("2".parse().unwrap(), Links::LabPackets));
        assert!(lab
            .iter()
            .all(|(p, t)| p != CFDP_SQL_FILE && !t.contains("Cfdp") && !t.contains("buckets:")));
    }

    // verifies: YAMCS-XTCE-01
    #[test]
    fn mode_cant_reach_reason_decodes_every_value_and_names_the_known_codes() {
        let x = yamcs_xtce(1);
        let start = x.find("name=\"MODE_CANT_REACH_reason_Type\"").expect("reason type");
        let ty = &x[start..start + x[start..].find("</xtce:EnumeratedParameterType>").unwrap()];
        assert!(
            ty.contains(&format!("value=\"0\" maxValue=\"65535\" label=\"{UNNAMED_VALUE}\"")),
            "{ty}"
        );
        for c in mib::FailureCode::ALL {
            assert!(
                ty.contains(&format!("value=\"{}\" label=\"{}\"", c.code(), c.name())),
                "{c:?}"
            );
        }
    }

    // verifies: YAMCS-CMD-01
    #[test]
    fn each_verifier_reads_the_request_id_of_its_own_stage_reports_only() {
        let x = yamcs_xtce(1);
        for (_, stage, sub, _) in STAGES {
            for s in [sub, sub + 1] {
                let start = x
                    .find(&format!("name=\"{VERIFICATION}_REPORT_{s}\""))
                    .unwrap_or_else(|| panic!("no container for TM[1,{s}]"));
                let c = &x[start..start + x[start..].find("</xtce:SequenceContainer>").unwrap()];
                assert!(
                    c.contains(&format!("parameterRef=\"TM_SUBSERVICE\" value=\"{s}\"")),
                    "{c}"
                );
                for f in ["apid", "seq_count", "subtype"] {
                    assert!(
                        c.contains(&format!("parameterRef=\"{}\"", stage_param(stage, f))),
                        "{c}"
                    );
                }
            }
            let start = x.find(&format!("Verifier name=\"{stage}\"")).unwrap();
            let v = &x[start..start + x[start..].find("</xtce:CustomAlgorithm>").unwrap()];
            for (f, input) in [("apid", "rcvdApid"), ("seq_count", "rcvdSeq"), ("subtype", "subtype")] {
                assert!(
                    v.contains(&format!(
                        "parameterRef=\"{}\" inputName=\"{input}\"",
                        stage_param(stage, f)
                    )),
                    "{v}"
                );
            }
        }
    }

    // verifies: YAMCS-VER-01
    #[test]
    fn every_verifier_is_judged_again_on_every_tm_packet() {
        let x = yamcs_xtce(1);
        // The trigger is a parameter of the TM header, i.e. of the abstract PUS_TM.
        let tm = x.find("<xtce:SequenceContainer name=\"PUS_TM\"").expect("PUS_TM");
        let tm = &x[tm..tm + x[tm..].find("</xtce:SequenceContainer>").unwrap()];
        assert!(tm.contains(&format!("parameterRef=\"{EVERY_TM_TRIGGER}\"")), "{tm}");
        for (_, stage, _, _) in STAGES {
            let start = x.find(&format!("Verifier name=\"{stage}\"")).unwrap();
            let v = &x[start..start + x[start..].find("</xtce:CustomAlgorithm>").unwrap()];
            // Pus1Verifier reads its first five inputs in this order; more are allowed.
            let inputs: Vec<&str> = v
                .split("inputName=\"")
                .skip(1)
                .map(|s| &s[..s.find('"').unwrap()])
                .collect();
            assert_eq!(
                inputs[..5],
                ["sentApid", "sentSeq", "rcvdApid", "rcvdSeq", "subtype"],
                "{v}"
            );
            assert!(
                v.contains(&format!("parameterRef=\"{EVERY_TM_TRIGGER}\" inputName=\"everyTm\"")),
                "{stage}: {v}"
            );
            // No trigger set narrows it again (a verifier runs when any input changes).
            assert!(!v.contains("TriggerSet"), "{v}");
        }
    }
}
