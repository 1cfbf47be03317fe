"""Drives a running Yamcs (the MMIC-I instance) through its REST/WebSocket API with
yamcs-client, for tests/tests/yamcs_e2e.rs. Collects facts, judges nothing: the Rust test
compares them with the MIB.

    python yamcs_check.py --url 127.0.0.1:PORT --instance mmic --robot 1 \
        --seconds 20 --commands commands.json --out result.json

commands.json: {"hk_params": [names of the HK parameters], "commands": [{"name": "PING",
"args": {...}, "at": seconds after the start, optional "tag", "schedule_in_s": time-tag the
command with Yamcs' pus11ScheduleAt that many seconds after issue (the result gives
schedule_at_unix_ms; "schedule_as": "datetime" passes a datetime instead of the string), "windows": {"Acceptance": stop s, ...} check windows, "bypass": true for a BD frame, "no_settle": true
not to wait for its final status (one Yamcs never completes)}, or {"cop1_init": "SET_VR", "v_r": 0, "link":
"tc_robot_1.vc0", "at": ...} (an operator's COP-1 initialisation)], "cop1_link": a link whose
COP-1 status is recorded at the start and the end, "settle_s": how long to wait at most after
the watch for every command's final status (default 15)}.
result.json:
  links:     [{name, status, in_count, out_count}]
  hk:        [{t (reception, s since start), sid, seq, params: {NAME: {raw, eng}}}], every HK report
  commands:  [{name, tag, id, args, schedule_at_unix_ms, attrs: {Verifier_*_Status / _Message,
             CommandComplete_*, binary, ccsds-seqcount, pus11-*}}]
  events:    [{type, severity, message, generation_time}]
  watched:   [{t, params}] every delivery with one of the plan's "watch" parameters
  alarms:    [{name, severity, violations, count, trigger_eng, trigger_raw}] the active parameter
             alarms at the end
  alarm_updates: [{t, type (TRIGGERED_PENDING, TRIGGERED, ...), name, violations}] as they came
  cop1:      {"start": status, "end": status} (state, v_s, nn_r) of plan["cop1_link"], if given
"""

import argparse
import datetime
import json
import os
import threading
import time

from yamcs.client import VerificationConfig, YamcsClient


def plain(v):
    if isinstance(v, datetime.datetime):
        return v.astimezone(datetime.timezone.utc).isoformat()
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    if isinstance(v, (bool, int, float, str)) or v is None:
        return v
    return str(v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--instance", default="mmic")
    ap.add_argument("--robot", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--commands", required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()

    ss = f"/MMIC_I_ROBOT_{a.robot}"
    client = YamcsClient(a.url)
    proc = client.get_processor(a.instance, "realtime")

    with open(a.commands) as f:
        plan = json.load(f)
    # The HK parameters to follow (the test takes them from the MIB), plus the headers
    # that identify the packet.
    names = [f"{ss}/{n}" for n in plan["hk_params"]]
    # Other parameters to record wherever they come (names relative to the robot's space
    # system, e.g. "MODULE_MODES/MODE_REPLY_mode").
    watch = [f"{ss}/{n}" for n in plan.get("watch", [])]
    headers = [f"{ss}/SRC_SEQ_CTR", f"{ss}/TM_TIME_DAYS", f"{ss}/TM_TIME_MS", f"{ss}/HK_SID"]

    t0 = time.monotonic()
    lock = threading.Lock()
    deliveries = []

    def on_data(delivery):
        now = time.monotonic() - t0
        vals = {}
        for pv in delivery.parameters:
            v = {"raw": plain(pv.raw_value), "eng": plain(pv.eng_value)}
            if isinstance(pv.eng_value, datetime.datetime):
                v["eng_unix_ms"] = round(pv.eng_value.timestamp() * 1000)
            vals[pv.name.rsplit("/", 1)[-1]] = v
        with lock:
            deliveries.append({"t": now, "params": vals})

    sub = proc.create_parameter_subscription(headers + names + watch, on_data=on_data, send_from_cache=False)

    hist = proc.create_command_history_subscription()
    events = []

    def on_event(ev):
        events.append({
            "type": ev.event_type,
            "severity": ev.severity,
            "message": ev.message,
            "generation_time": plain(ev.generation_time),
        })

    ev_sub = client.create_event_subscription(a.instance, on_data=on_event)

    alarm_updates = []

    def on_alarm(u):
        al = u.alarm
        with lock:
            alarm_updates.append({"t": time.monotonic() - t0, "type": u.update_type, "name": al.name,
                                  "violations": al.violation_count})

    al_sub = proc.create_alarm_subscription(on_data=on_alarm)

    def cop1_status():
        if not plan.get("cop1_link"):
            return None
        st = client.get_link(a.instance, plan["cop1_link"]).get_cop1_status()
        return {"active": st.cop1_active, "state": st.state, "v_s": st.v_s, "nn_r": st.nn_r}

    cop1 = {"start": cop1_status()}
    issued = []
    for c in sorted(plan["commands"], key=lambda c: c["at"]):
        wait = c["at"] - (time.monotonic() - t0)
        if wait > 0:
            time.sleep(wait)
        if "cop1_init" in c:
            client.get_link(a.instance, c["link"]).initialize_cop1(c["cop1_init"], v_r=c.get("v_r"))
            continue
        try:
            extra, verification = None, None
            if "schedule_in_s" in c:
                # Yamcs' own time-tagging: its PusCommandPostprocessor wraps the command
                # into a TC[11,4] (command option pus11ScheduleAt, "Schedule Time").
                at = datetime.datetime.now(datetime.timezone.utc) + datetime.timedelta(seconds=c["schedule_in_s"])
                at = at.replace(microsecond=(at.microsecond // 1000) * 1000)
                c = dict(c, schedule_at_unix_ms=round(at.timestamp() * 1000))
                # As the web UI sends it: a STRING that Yamcs coerces to its time. A datetime
                # ("schedule_as": "datetime") goes out as a TIMESTAMP Value with only its
                # stringValue set, which Yamcs 5.12.8 takes as it is: time 0 (docs/yamcs.md).
                if c.get("schedule_as") == "datetime":
                    extra = {"pus11ScheduleAt": at}
                else:
                    extra = {"pus11ScheduleAt": at.isoformat(timespec="milliseconds").replace("+00:00", "Z")}
            if c.get("bypass"):
                # "COP-1 Bypass": a BD frame (Yamcs' option cop1Bypass).
                extra = dict(extra or {}, cop1Bypass=True)
            if "windows" in c:
                # The operator's check windows (s after release), as in the web UI.
                verification = VerificationConfig()
                for stage, stop in c["windows"].items():
                    verification.modify_check_window(stage, start=None, stop=stop)
            cmd = proc.issue_command(f"{ss}/{c['name']}", args=c.get("args", {}), extra=extra,
                                     verification=verification)
            issued.append((c, cmd, None))
        except Exception as e:  # the test reports it
            issued.append((c, None, str(e)))
    rest = a.seconds - (time.monotonic() - t0)
    if rest > 0:
        time.sleep(rest)

    # Settle: wait (at most plan["settle_s"], default 15 s) until every issued command has
    # its final status, so that a loaded machine does not cut a verification short.
    settle_until = time.monotonic() + plan.get("settle_s", 15)
    while time.monotonic() < settle_until:
        pending = [cmd for c, cmd, _ in issued if cmd is not None and not c.get("no_settle") and
                   (hist.get_command_history(cmd) is None or
                    "CommandComplete_Status" not in hist.get_command_history(cmd).attributes)]
        if not pending:
            break
        time.sleep(0.2)

    commands = []
    for c, cmd, err in issued:
        attrs = {}
        if cmd is not None:
            h = hist.get_command_history(cmd)
            if h is not None:
                attrs = {k: plain(v) for k, v in h.attributes.items()
                         if k.startswith("Verifier_") or k.startswith("CommandComplete") or k == "binary"
                         or k.startswith("pus11") or k == "ccsds-seqcount"}
        commands.append({"name": c["name"], "tag": c.get("tag"), "id": cmd.id if cmd is not None else None,
                         "args": c.get("args", {}), "error": err,
                         "attrs": attrs, "schedule_at_unix_ms": c.get("schedule_at_unix_ms")})

    alarms = []
    for al in proc.list_alarms():
        tv = getattr(al, "trigger_value", None)
        alarms.append({"name": al.name, "severity": al.severity, "violations": al.violation_count,
                       "count": al.count,
                       "trigger_eng": plain(tv.eng_value) if tv is not None else None,
                       "trigger_raw": plain(tv.raw_value) if tv is not None else None})

    cop1["end"] = cop1_status()
    links = [{"name": l.name, "status": l.status, "in_count": l.in_count, "out_count": l.out_count}
             for l in client.list_links(a.instance)]

    hk_out = []
    with lock:
        watched = [d for d in deliveries
                   if any(w.rsplit("/", 1)[-1] in d["params"] for w in watch)]
        for d in deliveries:
            p = d["params"]
            if "HK_SID" not in p:
                continue
            hk_out.append({"t": d["t"], "sid": p["HK_SID"]["eng"],
                           "seq": p.get("SRC_SEQ_CTR", {}).get("raw"), "params": p})

    with open(a.out, "w") as f:
        json.dump({"links": links, "hk": hk_out, "watched": watched, "commands": commands, "events": events, "alarms": alarms,
                   "alarm_updates": alarm_updates, "cop1": cop1,
                   "hk_names": [n.rsplit("/", 1)[-1] for n in names]}, f, indent=1)
    # Closing the WebSocket subscriptions takes seconds; the process ends them.
    os._exit(0)


if __name__ == "__main__":
    main()
