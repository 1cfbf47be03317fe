"""Screenshots of Yamcs' web pages in headless Chromium (DevTools protocol), for
docs/yamcs.md. Needs a running Yamcs and `chromium`; runs in the Yamcs venv (it has
websocket-client).

    python yamcs_screens.py --url http://127.0.0.1:8090 --out docs/img \
        yamcs-commands=/commanding/history?c=mmic__realtime ...

Each NAME=PATH is loaded, given --wait seconds to render (the pages keep WebSockets
open, so "load finished" never comes), and written to OUT/NAME.png. NAME=PATH!TEXT also
clicks the innermost element whose text is TEXT (e.g. a collapsed "Advanced options" step)
and scrolls it to the top before the screenshot.
"""

import argparse
import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request

import websocket


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--wait", type=float, default=6.0)
    ap.add_argument("--port", type=int, default=9333)
    ap.add_argument("pages", nargs="+")
    a = ap.parse_args()

    profile = tempfile.mkdtemp(prefix="yamcs-shots-")
    chrome = subprocess.Popen(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         f"--remote-debugging-port={a.port}", f"--user-data-dir={profile}",
         "--window-size=1400,900", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{a.port}/json"))
                break
            except OSError:
                time.sleep(0.2)
        page = next(t for t in targets if t["type"] == "page")
        ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60)
        seq = [0]

        def call(method, **params):
            seq[0] += 1
            ws.send(json.dumps({"id": seq[0], "method": method, "params": params}))
            while True:
                msg = json.loads(ws.recv())
                if msg.get("id") == seq[0]:
                    return msg.get("result", {})

        call("Emulation.setDeviceMetricsOverride", width=1400, height=900, deviceScaleFactor=1, mobile=False)
        os.makedirs(a.out, exist_ok=True)
        for spec in a.pages:
            name, path = spec.split("=", 1)
            path, _, click = path.partition("!")
            call("Page.navigate", url=a.url + path)
            time.sleep(a.wait)
            if click:
                js = ("(() => { const all = [...document.querySelectorAll('*')]"
                      ".filter(e => e.children.length === 0 && e.textContent.trim() === %s);"
                      " if (!all.length) return false; const e = all[0]; e.click();"
                      " e.scrollIntoView({block: 'start'}); return true; })()") % json.dumps(click)
                clicked = call("Runtime.evaluate", expression=js, returnByValue=True)
                if not clicked.get("result", {}).get("value"):
                    raise SystemExit(f"{name}: no element with the text {click!r} on {path}")
                time.sleep(2.0)
            png = call("Page.captureScreenshot", format="png")["data"]
            out = os.path.join(a.out, name + ".png")
            with open(out, "wb") as f:
                f.write(base64.b64decode(png))
            print(out)
        ws.close()
    finally:
        chrome.terminate()
        chrome.wait(timeout=10)
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    main()
