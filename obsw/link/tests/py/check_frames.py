#!/usr/bin/env python3
"""Independent check of MMIC-I space-link frames, written from the standards, not from the
Rust code:

- CCSDS 232.0-B-4 §4.1 (TC transfer frame: 5-byte primary header, FECF),
- CCSDS 132.0-B-3 §4.1 (TM transfer frame: 6-byte primary header, data field status,
  OCF, FECF) and 232.0-B-4 §4.2.1 (the CLCW in the OCF),
- CCSDS 355.0-B-2 with AES-256-GCM in Yamcs 5.12.8's layout: security header = 2-byte SPI
  + 12-byte IV, 16-byte MAC trailer, AAD = frame header + security header ANDed with Yamcs'
  default mask (TC: 00 00 FC 00 00 | FF FF | 12 x 00; TM: 00 0E 00 00 00 00 | FF FF | 12 x 00).

Usage: check_frames.py DIR --key SPI=HEX [--key SPI=HEX ...]
Reads DIR/*.tc and DIR/*.tm (one frame per file; DIR/*.tmclear: TM frames without SDLS,
the whole data field is the packet zone), prints one line per file:
    <name> OK <fields...> data=<hex>
    <name> BAD <reason>
Exit status 0 when every file was examined (BAD lines are results, not failures).
"""

import pathlib
import sys

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives.ciphers.aead import AESGCM


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final XOR."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


TC_MASK = bytes([0x00, 0x00, 0xFC, 0x00, 0x00, 0xFF, 0xFF] + [0x00] * 12)
TM_MASK = bytes([0x00, 0x0E, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF] + [0x00] * 12)


def masked(frame: bytes, mask: bytes) -> bytes:
    return bytes(f & m for f, m in zip(frame[: len(mask)], mask))


def open_sdls(keys, frame: bytes, hdr_len: int, data_end: int, mask: bytes):
    """Returns (spi, iv_int, plaintext) or raises ValueError with the reason."""
    if data_end - hdr_len < 14 + 16:
        raise ValueError("sdls-too-short")
    spi = int.from_bytes(frame[hdr_len : hdr_len + 2], "big")
    iv = frame[hdr_len + 2 : hdr_len + 14]
    if spi not in keys:
        raise ValueError(f"unknown-spi-{spi}")
    ct_and_tag = frame[hdr_len + 14 : data_end]
    try:
        pt = AESGCM(keys[spi]).decrypt(iv, ct_and_tag, masked(frame, mask))
    except InvalidTag:
        raise ValueError("mac") from None
    return spi, int.from_bytes(iv, "big"), pt


def check_tc(keys, frame: bytes) -> str:
    if len(frame) < 7:
        return "BAD short"
    w0 = int.from_bytes(frame[0:2], "big")
    w1 = int.from_bytes(frame[2:4], "big")
    version = w0 >> 14
    bypass = (w0 >> 13) & 1
    ctrl = (w0 >> 12) & 1
    spare = (w0 >> 10) & 3
    scid = w0 & 0x3FF
    vcid = w1 >> 10
    length = (w1 & 0x3FF) + 1
    seq = frame[4]
    if length != len(frame):
        return f"BAD length header={length} file={len(frame)}"
    if crc16_ccitt_false(frame[:-2]) != int.from_bytes(frame[-2:], "big"):
        return "BAD crc"
    if version != 0 or spare != 0:
        return "BAD header"
    kind = {(0, 0): "AD", (1, 0): "BD", (1, 1): "BC"}.get((bypass, ctrl))
    if kind is None:
        return "BAD frame-type"
    head = f"type={kind} scid={scid:#05x} vc={vcid} seq={seq}"
    data = frame[5:-2]
    if kind == "BC":
        if data == b"\x00":
            return f"OK {head} cmd=unlock"
        if len(data) == 3 and data[0] == 0x82 and data[1] == 0x00:
            return f"OK {head} cmd=setvr-{data[2]}"
        return f"BAD control-command {data.hex()}"
    try:
        spi, iv, pt = open_sdls(keys, frame, 5, len(frame) - 2, TC_MASK)
    except ValueError as e:
        return f"BAD {e}"
    return f"OK {head} spi={spi} iv={iv} data={pt.hex()}"


def clcw_text(word: int) -> str:
    if word >> 31:
        return "clcw=type2"
    return (
        f"clcw_version={(word >> 29) & 3} cop={(word >> 24) & 3} clcw_vc={(word >> 18) & 0x3F} "
        f"lockout={(word >> 13) & 1} wait={(word >> 12) & 1} retransmit={(word >> 11) & 1} "
        f"farmb={(word >> 9) & 3} nr={word & 0xFF}"
    )


def check_tm(keys, frame: bytes, clear: bool = False) -> str:
    if len(frame) < 12:
        return "BAD short"
    if crc16_ccitt_false(frame[:-2]) != int.from_bytes(frame[-2:], "big"):
        return "BAD crc"
    w0 = int.from_bytes(frame[0:2], "big")
    version = w0 >> 14
    scid = (w0 >> 4) & 0x3FF
    vcid = (w0 >> 1) & 7
    ocf_flag = w0 & 1
    mc, vcc = frame[2], frame[3]
    dfs = int.from_bytes(frame[4:6], "big")
    sec_hdr, sync, order, seg = dfs >> 15, (dfs >> 14) & 1, (dfs >> 13) & 1, (dfs >> 11) & 3
    fhp = dfs & 0x7FF
    if version != 0 or sec_hdr or sync or order or seg != 3 or not ocf_flag:
        return "BAD header"
    ocf = int.from_bytes(frame[-6:-2], "big")
    head = f"scid={scid:#05x} vc={vcid} mc={mc} vcc={vcc} fhp={fhp:#05x} len={len(frame)} {clcw_text(ocf)}"
    data_end = len(frame) - 6
    if fhp == 0x7FE:
        return f"OK {head} idle=1"
    if clear:
        spi, iv, pt = None, None, frame[6:data_end]
    else:
        try:
            spi, iv, pt = open_sdls(keys, frame, 6, data_end, TM_MASK)
        except ValueError as e:
            return f"BAD {e}"
    # The first packet starting in this frame, from the first header pointer.
    first = ""
    if fhp != 0x7FF and fhp + 6 <= len(pt):
        ph = pt[fhp : fhp + 6]
        apid = int.from_bytes(ph[0:2], "big") & 0x7FF
        plen = int.from_bytes(ph[4:6], "big") + 7
        first = f" first_apid={apid} first_len={plen}"
    sec = "sdls=none" if clear else f"spi={spi} iv={iv}"
    return f"OK {head} {sec}{first} data={pt.hex()}"


def main(argv) -> int:
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    directory = pathlib.Path(argv[1])
    keys = {}
    i = 2
    while i < len(argv):
        if argv[i] == "--key" and i + 1 < len(argv):
            spi, hexkey = argv[i + 1].split("=", 1)
            keys[int(spi)] = bytes.fromhex(hexkey)
            i += 2
        else:
            print(f"unknown argument {argv[i]}", file=sys.stderr)
            return 2
    for path in sorted(directory.iterdir()):
        frame = path.read_bytes()
        if path.suffix == ".tc":
            print(f"{path.name} {check_tc(keys, frame)}")
        elif path.suffix == ".tm":
            print(f"{path.name} {check_tm(keys, frame)}")
        elif path.suffix == ".tmclear":
            print(f"{path.name} {check_tm(keys, frame, clear=True)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
