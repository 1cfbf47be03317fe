//! `ground update keygen|sign|install|activate`: software update in flight (docs/update.md).
//!
//! The ground holds the update signing key (Ed25519, `keygen`), signs an image (`sign`: the
//! header of `mib::update` over the payload), puts it into the robot's file store with
//! `ground file put`, then asks the robot to install it into its inactive slot (`install`:
//! UPDATE_INSTALL, the robot verifies the signature and digest) and to boot it (`activate`:
//! UPDATE_ACTIVATE, hazardous, carrying the image's SHA-256 read from the signed file, so
//! that an activation can only name the image the operator holds).

use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{anyhow, Context, Result};
use clap::{Subcommand, ValueEnum};
use mib::update::{field, target, DIGEST_LEN, HEADER_LEN};
use mmic_update::host::hex32;
use mmic_update::image::{self, Header};

use crate::exit::{self, coded};
use crate::links::{open_one, Links};
use crate::verb_live::send_and_follow;

#[derive(Subcommand, Debug)]
pub(crate) enum UpdateCmd {
    /// Create the update signing key: DIR/update.key (secret, mode 0600) and DIR/update.pub
    /// (the robot's `--update-key`). Refuses to overwrite a key.
    Keygen { dir: PathBuf },
    /// Sign PAYLOAD as an image (header: version, length, target, SHA-256, Ed25519 signature).
    Sign {
        /// The secret key file of `keygen`.
        #[arg(long)]
        key: PathBuf,
        /// Software version MAJOR.MINOR.PATCH (each 0..=255).
        #[arg(long)]
        version: String,
        /// What the payload runs on.
        #[arg(long, value_enum)]
        target: TargetArg,
        payload: PathBuf,
        /// The signed image to write.
        out: PathBuf,
    },
    /// Install an image of the robot's file store (put there with `ground file put`) into
    /// its inactive slot; the robot verifies it there.
    Install {
        #[command(flatten)]
        links: Links,
        /// The image's name in the robot's store.
        name: String,
        #[arg(long, default_value_t = 60.0)]
        timeout: f64,
    },
    /// Boot the installed image: UPDATE_ACTIVATE with the SHA-256 of the local signed IMAGE
    /// (hazardous: needs --confirm). The robot resets into it; it confirms itself after its
    /// self-test or the next boot returns to the running image.
    Activate {
        #[command(flatten)]
        links: Links,
        /// The signed image that was installed (its digest names it to the robot).
        image: PathBuf,
        #[arg(long)]
        confirm: bool,
        #[arg(long, default_value_t = 60.0)]
        timeout: f64,
    },
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum TargetArg {
    /// The host obsw (the payload is the start file `obsw-boot` executes).
    Host,
    /// Board A's ESP32-C3 application image.
    BoardA,
}

pub(crate) fn update(cmd: &UpdateCmd) -> Result<u8> {
    match cmd {
        UpdateCmd::Keygen { dir } => keygen(dir),
        UpdateCmd::Sign {
            key,
            version,
            target: t,
            payload,
            out,
        } => sign(key, version, *t, payload, out),
        UpdateCmd::Install { links, name, timeout } => install(links, name, *timeout),
        UpdateCmd::Activate {
            links,
            image,
            confirm,
            timeout,
        } => activate(links, image, *confirm, *timeout),
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn keygen(dir: &Path) -> Result<u8> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    let secret = ground::keys::random_key().map_err(|e| anyhow!("{e}"))?;
    let (sk, pk) = (dir.join("update.key"), dir.join("update.pub"));
    for p in [&sk, &pk] {
        if p.exists() {
            return Err(coded(exit::INVALID, format!("{} exists: not overwritten", p.display())));
        }
    }
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&sk)
        .with_context(|| format!("{}", sk.display()))?;
    std::io::Write::write_all(&mut f, format!("{}\n", hex(&secret)).as_bytes())?;
    std::fs::write(&pk, format!("{}\n", hex(&image::public_key(&secret))))
        .with_context(|| format!("{}", pk.display()))?;
    println!(
        "update key: {} (secret), {} (for the robot)",
        sk.display(),
        pk.display()
    );
    Ok(exit::OK)
}

fn parse_version(v: &str) -> Option<u32> {
    let mut it = v.split('.').map(|p| p.parse::<u32>().ok());
    let (a, b, c) = (it.next()??, it.next()??, it.next()??);
    if it.next().is_some() {
        return None;
    }
    mib::update::version::pack(a, b, c)
}

fn sign(key: &Path, version: &str, t: TargetArg, payload: &Path, out: &Path) -> Result<u8> {
    let text = std::fs::read_to_string(key).with_context(|| format!("--key {}", key.display()))?;
    let secret = hex32(text.trim()).ok_or_else(|| {
        coded(
            exit::INVALID,
            format!("--key {}: not 64 hexadecimal digits", key.display()),
        )
    })?;
    let v = parse_version(version).ok_or_else(|| {
        coded(
            exit::INVALID,
            format!("--version {version}: not MAJOR.MINOR.PATCH (0..=255 each)"),
        )
    })?;
    let body = std::fs::read(payload).with_context(|| format!("{}", payload.display()))?;
    let t = match t {
        TargetArg::Host => target::HOST,
        TargetArg::BoardA => target::BOARD_A,
    };
    let header = image::sign(&secret, v, t, &body)
        .ok_or_else(|| coded(exit::INVALID, format!("{}: larger than 4 GiB", payload.display())))?;
    let mut img = header.to_vec();
    img.extend_from_slice(&body);
    std::fs::write(out, &img).with_context(|| format!("{}", out.display()))?;
    println!(
        "{}: version {version}, {} bytes, sha256 {}",
        out.display(),
        body.len(),
        hex(&header[field::DIGEST..field::DIGEST + DIGEST_LEN])
    );
    Ok(exit::OK)
}

fn install(links: &Links, name: &str, timeout: f64) -> Result<u8> {
    mmic_cfdp::FileName::new(name).map_err(|e| coded(exit::INVALID, format!("store name {name:?}: {e:?}")))?;
    let def = mib::tc::by_name("UPDATE_INSTALL").ok_or_else(|| anyhow!("UPDATE_INSTALL not in the MIB"))?;
    let mut args = vec![name.len() as i64];
    args.extend(name.bytes().map(i64::from));
    let (robot, mut s, _) = open_one(links, None)?;
    send_and_follow(&mut s, robot, def, &args, true, Duration::from_secs_f64(timeout))
}

/// The header of a signed image file.
fn header_of(path: &Path) -> Result<Header> {
    let b = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
    let h: &[u8; HEADER_LEN] = b.get(..HEADER_LEN).and_then(|h| h.try_into().ok()).ok_or_else(|| {
        coded(
            exit::INVALID,
            format!("{}: shorter than an image header", path.display()),
        )
    })?;
    Header::parse(h).map_err(|e| coded(exit::INVALID, format!("{}: {e}", path.display())))
}

fn activate(links: &Links, path: &Path, confirm: bool, timeout: f64) -> Result<u8> {
    let def = mib::tc::by_name("UPDATE_ACTIVATE").ok_or_else(|| anyhow!("UPDATE_ACTIVATE not in the MIB"))?;
    if !confirm {
        return Err(coded(
            exit::INVALID,
            "UPDATE_ACTIVATE is hazardous (replaces the running software): add --confirm",
        ));
    }
    let h = header_of(path)?;
    let args: Vec<i64> = h
        .digest
        .chunks_exact(4)
        .map(|w| i64::from(u32::from_be_bytes([w[0], w[1], w[2], w[3]])))
        .collect();
    let (robot, mut s, _) = open_one(links, None)?;
    send_and_follow(&mut s, robot, def, &args, true, Duration::from_secs_f64(timeout))
}
