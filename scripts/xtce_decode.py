#!/usr/bin/env python3
"""Decode CCSDS packets with an independent XTCE decoder (space-packet-parser).

Usage: xtce_decode.py [--no-validate] XTCE_FILE PACKET_FILE

XTCE_FILE   the MIB's XTCE export (mib_export::xtce_document)
PACKET_FILE concatenated CCSDS space packets

Prints one JSON document on stdout:
  {"decoder": "space-packet-parser X.Y.Z",
   "validation": {"schema_valid": true, "structure_errors": [...], "tolerated": [...]},
   "packets": [{"<parameter>": {"raw": <raw value>, "value": <calibrated value>}, ...}, ...]}

Binary values are hex strings, booleans true/false. The XTCE document is first validated
against the XTCE 1.2 XSD bundled with space-packet-parser (no network access); a schema
error, or a structural error other than the tolerated one below, exits with status 1.

Tolerated structural finding: space-packet-parser's structure check only knows
SequenceContainers, so it reports the BaseContainer of every telecommand CommandContainer
(which refers to the abstract PUS_TC CommandContainer, as XTCE allows) as missing. It is
tolerated only when the referenced name is a CommandContainer of the document.

Run scripts/python-env.sh first; it installs the pinned space-packet-parser into .venv.
"""

import json
import logging
import sys
import warnings
from importlib import metadata
from pathlib import Path


def fail(msg: str) -> None:
    print(f"xtce_decode.py: {msg}", file=sys.stderr)
    sys.exit(1)


def to_json(v):
    # Imported lazily so that --help works without the package.
    from space_packet_parser.common import BinaryParameter, BoolParameter

    if isinstance(v, BinaryParameter):
        return bytes(v).hex()
    if isinstance(v, BoolParameter):
        return bool(v)
    if isinstance(v, bytes):
        return v.hex()
    if isinstance(v, bool):
        return v
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        return float(v)
    return str(v)


def validate(xtce_path: Path) -> dict:
    import lxml.etree as etree
    from space_packet_parser.xtce import validation

    xsd = Path(validation.__file__).parent / "schemas" / "SpaceSystem.xsd"
    # The findings are reported in the JSON document; keep stderr for real failures.
    logging.getLogger("space_packet_parser").setLevel(logging.CRITICAL)
    result = validation.validate_xtce(
        str(xtce_path),
        level="all",
        local_xsd=xsd,
        allow_schema_download=False,
        raise_on_error=False,
        print_results=False,
    )
    tree = etree.parse(str(xtce_path))
    ns = {"xtce": tree.getroot().nsmap.get("xtce", "")}
    command_containers = {
        e.get("name") for e in tree.getroot().iterfind(".//xtce:CommandContainer", ns)
    }
    schema_errors, structure_errors, tolerated = [], [], []
    for e in result.errors:
        text = str(e)
        if e.error_code == "SCHEMA_VALIDATION_ERROR" or e.error_code.startswith("SCHEMA"):
            schema_errors.append(text)
        elif (
            e.error_code == "MISSING_CONTAINER_REFERENCE"
            and e.xpath_location
            and any(f"'{c}'" in e.xpath_location for c in command_containers)
        ):
            tolerated.append(text)
        else:
            structure_errors.append(text)
    return {
        "schema_valid": not schema_errors,
        "schema_errors": schema_errors,
        "structure_errors": structure_errors,
        "tolerated": sorted(set(tolerated)),
    }


def main(argv) -> None:
    args = [a for a in argv if not a.startswith("--")]
    if "--help" in argv or "-h" in argv or len(args) != 2:
        print(__doc__)
        sys.exit(0 if ("--help" in argv or "-h" in argv) else 2)
    xtce_path, packet_path = Path(args[0]), Path(args[1])
    if not xtce_path.is_file():
        fail(f"no XTCE file {xtce_path}")
    if not packet_path.is_file():
        fail(f"no packet file {packet_path}")
    try:
        import space_packet_parser as spp
    except ImportError:
        fail("space_packet_parser is not installed: run scripts/python-env.sh and use .venv/bin/python")

    report = {"decoder": f"space-packet-parser {metadata.version('space_packet_parser')}"}
    if "--no-validate" not in argv:
        v = validate(xtce_path)
        report["validation"] = v
        if not v["schema_valid"] or v["structure_errors"]:
            print(json.dumps(report, indent=1))
            fail("the XTCE document is not valid (see the validation report above)")

    definition = spp.load_xtce(xtce_path)
    packets = []
    with packet_path.open("rb") as f:
        for raw in spp.ccsds_generator(f):
            # A length mismatch is only a warning in space-packet-parser: make it fatal.
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                pkt = definition.parse_bytes(bytes(raw))
            values = {}
            for name, value in pkt.items():
                raw_value = getattr(value, "raw_value", value)
                values[name] = {"raw": to_json(raw_value), "value": to_json(value)}
            packets.append(values)
    report["packets"] = packets
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main(sys.argv[1:])
