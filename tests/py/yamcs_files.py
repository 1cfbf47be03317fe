"""Moves files through a running Yamcs' CFDP service (the MMIC-I instance) with yamcs-client's
file-transfer API, as an operator would, for tests/tests/yamcs_e2e.rs. Collects facts,
judges nothing: the Rust test compares the bytes with the robot's file store.

    python yamcs_files.py --url 127.0.0.1:PORT --instance mmic --service cfdp \
        --plan files.json --out result.json

files.json: {"local": "ground", "remote": "robot-1", "up_bucket": "cfdpUp",
"down_bucket": "cfdpDown", "timeout_s": 60, "steps": [
  {"op": "upload", "object": NAME in up_bucket, "remote_path": NAME on board, "reliable": bool},
  {"op": "download", "remote_path": NAME on board, "object": NAME in down_bucket, "reliable": bool}]}
Steps run one after the other.
result.json:
  service:  {local: [names], remote: [names], capabilities: {...}}
  steps:    [{op, reliable, seconds, transfers: [{id, direction, state, reliable, object, remote_path,
            total, transferred, failure, transaction}], object (download: the name Yamcs stored it
            under), data_hex (download: the object's bytes read back through the bucket API)}]
An upload step ends when its transfer ends. A download step is Yamcs' proxy put request (an
upload of metadata) and the robot's put back (an incoming transfer Yamcs creates): it ends
when the incoming transfer of that remote path ends.
"""

import argparse
import json
import time

from yamcs.client import YamcsClient
from yamcs.protobuf.filetransfer import filetransfer_pb2 as ft

ENDED = (ft.TransferState.COMPLETED, ft.TransferState.FAILED)


def transfers(client, instance, service):
    r = client.ctx.get_proto(f"/filetransfer/{instance}/{service}/transfers")
    m = ft.ListTransfersResponse()
    m.ParseFromString(r.content)
    # The list can name a transfer twice (ongoing and recorded): the last word counts.
    return list({t.id: t for t in m.transfers}.values())


def plain(t):
    return {
        "id": t.id,
        "direction": ft.TransferDirection.Name(t.direction),
        "state": ft.TransferState.Name(t.state),
        "reliable": t.reliable,
        "object": t.objectName,
        "remote_path": t.remotePath,
        "total": t.totalSize,
        "transferred": t.sizeTransferred,
        "failure": t.failureReason,
        "transaction": f"{t.transactionId.initiatorEntity}/{t.transactionId.sequenceNumber}",
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--instance", default="mmic")
    ap.add_argument("--service", default="cfdp")
    ap.add_argument("--plan", required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    plan = json.load(open(a.plan))

    client = YamcsClient(a.url)
    svc = client.get_file_transfer_client(a.instance).get_service(a.service)
    storage = client.get_storage_client()
    result = {
        "service": {
            "local": [e.name for e in svc.local_entities],
            "remote": [e.name for e in svc.remote_entities],
            "capabilities": {
                "upload": svc.capabilities.upload,
                "download": svc.capabilities.download,
                "filelist": svc.capabilities.filelist,
            },
        },
        "steps": [],
    }
    timeout = plan.get("timeout_s", 60)
    for step in plan["steps"]:
        before = {t.id for t in transfers(client, a.instance, a.service)}
        t0 = time.monotonic()
        if step["op"] == "upload":
            svc.upload(plan["up_bucket"], step["object"], step["remote_path"],
                       source_entity=plan["local"], destination_entity=plan["remote"],
                       options={"reliable": step["reliable"]})
        else:
            svc.download(plan["down_bucket"], step["remote_path"], step["object"],
                         source_entity=plan["remote"], destination_entity=plan["local"],
                         options={"reliable": step["reliable"]})
        out = {"op": step["op"], "reliable": step["reliable"], "transfers": []}
        while time.monotonic() - t0 < timeout:
            new = [t for t in transfers(client, a.instance, a.service) if t.id not in before]
            mine = [t for t in new if step["op"] == "upload"
                    or (t.direction == ft.TransferDirection.DOWNLOAD and t.remotePath == step["remote_path"])]
            out["transfers"] = [plain(t) for t in new]
            # Yamcs 5.12.8 waits for an ACK of its class 1 Finished PDU, which 727.0-B-5 does not
            # send (docs/files.md, "Yamcs"): a class 1 download also ends when its file is in
            # the bucket.
            ended = bool(mine) and all(t.state in ENDED for t in new)
            class1_arrived = (step["op"] == "download" and len(mine) == 1 and not mine[0].reliable
                              and mine[0].totalSize > 0 and mine[0].sizeTransferred == mine[0].totalSize)
            if step["op"] == "upload" and ended:
                break
            if step["op"] == "download" and (ended or class1_arrived):
                out["object"] = mine[0].objectName
                try:
                    out["data_hex"] = storage.download_object(plan["down_bucket"], mine[0].objectName).hex()
                    break
                except Exception as e:  # not (yet) in the bucket
                    out["bucket_error"] = str(e)
                    if ended:
                        break
            time.sleep(0.2)
        out["seconds"] = round(time.monotonic() - t0, 2)
        result["steps"].append(out)
    json.dump(result, open(a.out, "w"), indent=1)


if __name__ == "__main__":
    main()
