"""A tiny W3C WebDriver client for headless Chromium, standard library only (no selenium).

    with Browser() as b:
        b.open(Path("report/index.html").resolve().as_uri())
        title = b.script("return document.querySelector('h1').textContent")
        b.click(b.find("table#pairs th"))
        b.screenshot("shot.png", full_page=True)

`Browser` starts `chromedriver` on a free port, opens one session on Chromium with a fresh temporary
profile (and XDG config/cache folders, so nothing is written under ~/.config), and on exit (or on any
failure while starting) deletes the session, stops the driver, stops any browser process still running on
that folder, and removes it.
"""

from __future__ import annotations

import atexit
import base64
import json
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

# The key of an element reference in W3C WebDriver JSON.
ELEMENT_KEY = "element-6066-11e4-a52e-4f735466cecf"

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
DRIVER_NAMES = ("chromedriver",)

# The most a full-page screenshot grows the window to.
MAX_SHOT_HEIGHT = 8000


class WebDriverError(RuntimeError):
    """A failed WebDriver command (with the W3C error code and message) or a driver that did not start."""

    def __init__(self, message: str, error: str | None = None):
        super().__init__(message)
        self.error = error


def _which(path: str, names: tuple[str, ...]) -> str | None:
    if os.access(path, os.X_OK) and Path(path).is_file():
        return path
    for n in names:
        found = shutil.which(n)
        if found:
            return found
    return None


def find_chromium() -> str | None:
    """/usr/bin/chromium, else the first Chromium or Chrome on PATH (env CHROMIUM_BIN overrides)."""
    env = os.environ.get("CHROMIUM_BIN")
    if env:
        return env if os.access(env, os.X_OK) else None
    return _which("/usr/bin/chromium", CHROMIUM_NAMES)


def find_chromedriver() -> str | None:
    """/usr/bin/chromedriver, else chromedriver on PATH (env CHROMEDRIVER_BIN overrides)."""
    env = os.environ.get("CHROMEDRIVER_BIN")
    if env:
        return env if os.access(env, os.X_OK) else None
    return _which("/usr/bin/chromedriver", DRIVER_NAMES)


def missing() -> list[str]:
    """What is missing to run a browser: empty when Chromium and chromedriver were both found."""
    out = []
    if find_chromium() is None:
        out.append("chromium (/usr/bin/chromium or on PATH; Debian: apt-get install chromium)")
    if find_chromedriver() is None:
        out.append("chromedriver (/usr/bin/chromedriver or on PATH; Debian: apt-get install chromium-driver)")
    return out


def available() -> bool:
    """Whether Chromium and chromedriver are both installed."""
    return not missing()


def chromium_args(profile_dir: str, width: int = 1400, height: int = 1800) -> list[str]:
    """The Chromium flags: headless, as root (no sandbox), no GPU, and nothing that reaches the network."""
    return [
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-dev-shm-usage",
        f"--user-data-dir={profile_dir}",
        f"--window-size={width},{height}",
        "--allow-file-access-from-files",
    ]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tail(path: Path, n: int = 4000) -> str:
    try:
        data = path.read_bytes()
    except OSError:
        return ""
    return data[-n:].decode("utf-8", "replace").strip()


def _pids_using(workdir: str) -> list[int]:
    """Live processes whose command line names this session's folder: its browser and the browser's
    helpers (the profile is `--user-data-dir` of each; the crash handler's database is under the folder's
    XDG_CONFIG_HOME). Zombies (already dead, waiting to be reaped by their parent) are not counted."""
    needle = workdir.encode()
    pids = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            if needle not in (d / "cmdline").read_bytes():
                continue
            state = (d / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if state not in ("Z", "X"):
            pids.append(int(d.name))
    return pids


class Browser:
    """One headless Chromium session driven over W3C WebDriver. Use as a context manager."""

    def __init__(
        self,
        width: int = 1400,
        height: int = 1800,
        chromium: str | None = None,
        chromedriver: str | None = None,
        start_timeout: float = 60.0,
        command_timeout: float = 120.0,
    ):
        self.width, self.height = width, height
        self.chromium = chromium or find_chromium()
        self.chromedriver = chromedriver or find_chromedriver()
        self.start_timeout = start_timeout
        self.command_timeout = command_timeout
        self.driver: subprocess.Popen | None = None
        self.session: str | None = None
        self.port: int | None = None
        self.profile: str | None = None
        self.workdir: str | None = None
        self.startup_seconds: float | None = None

    # -- lifetime ------------------------------------------------------------------------------------

    def __enter__(self) -> "Browser":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self) -> None:
        """Start chromedriver and open a session; everything started is cleaned up if any step fails."""
        if not self.chromium or not self.chromedriver:
            raise WebDriverError("cannot start a browser; missing: " + "; ".join(missing()))
        t0 = time.monotonic()
        # Cleaned up even if the interpreter exits without closing (an interrupted test run).
        atexit.register(self.close)
        try:
            self.workdir = tempfile.mkdtemp(prefix="ogm-browser-")
            self.profile = os.path.join(self.workdir, "profile")
            os.mkdir(self.profile)
            self._driver_log = Path(self.workdir) / "chromedriver.log"
            self._start_driver()
            caps = {
                "capabilities": {
                    "alwaysMatch": {
                        "browserName": "chrome",
                        "pageLoadStrategy": "normal",
                        "goog:chromeOptions": {
                            "binary": self.chromium,
                            "args": chromium_args(self.profile, self.width, self.height),
                        },
                        "goog:loggingPrefs": {"browser": "ALL"},
                    }
                }
            }
            try:
                value = self._request("POST", "/session", caps, timeout=self.start_timeout)
            except WebDriverError as e:
                raise WebDriverError(
                    f"chromedriver could not start {self.chromium}: {e}\n"
                    f"--- chromedriver log (tail) ---\n{_tail(self._driver_log)}",
                    e.error,
                ) from None
            self.session = value["sessionId"]
            self._request("POST", self._s("/timeouts"), {"pageLoad": 60000, "script": 30000, "implicit": 0})
        except BaseException:
            self.close()
            raise
        self.startup_seconds = time.monotonic() - t0

    def _start_driver(self) -> None:
        self.port = _free_port()
        # The browser inherits this environment: its config and cache (the crash handler's database among
        # them) go to the session's folder, not to ~/.config/chromium.
        env = dict(os.environ)
        for var, sub in (("XDG_CONFIG_HOME", "config"), ("XDG_CACHE_HOME", "cache")):
            env[var] = os.path.join(self.workdir, sub)
            os.makedirs(env[var], exist_ok=True)
        log = open(self._driver_log, "wb")
        try:
            self.driver = subprocess.Popen(
                [self.chromedriver, f"--port={self.port}", "--enable-chrome-logs"],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,  # its own process group: stopped as one in close()
            )
        finally:
            log.close()
        deadline = time.monotonic() + self.start_timeout
        while True:
            if self.driver.poll() is not None:
                raise WebDriverError(
                    f"chromedriver exited with status {self.driver.returncode} before it was ready\n"
                    f"--- chromedriver output (tail) ---\n{_tail(self._driver_log)}"
                )
            try:
                value = self._request("GET", "/status", timeout=2)
                if value.get("ready"):
                    return
            except (WebDriverError, OSError):
                pass
            if time.monotonic() > deadline:
                raise WebDriverError(
                    f"chromedriver not ready on port {self.port} after {self.start_timeout:.0f} s\n"
                    f"--- chromedriver output (tail) ---\n{_tail(self._driver_log)}"
                )
            time.sleep(0.05)

    def close(self) -> None:
        """Delete the session, stop the driver and any browser left on the profile, remove the profile.
        Safe to call more than once."""
        atexit.unregister(self.close)
        if self.session is not None:
            try:
                self._request("DELETE", self._s(""), timeout=30)
            except Exception:
                pass
            self.session = None
        if self.driver is not None:
            if self.driver.poll() is None:
                try:
                    self.driver.terminate()
                    self.driver.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.driver.kill()
                    self.driver.wait(timeout=10)
            # Anything else in the driver's process group (a browser it started that outlived it).
            try:
                os.killpg(self.driver.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            self.driver = None
        if self.workdir is not None:
            # A browser process outside the driver's process group (Chromium's crash handler starts its
            # own session) still names the session's folder.
            for _ in range(50):
                pids = _pids_using(self.workdir)
                if not pids:
                    break
                for pid in pids:
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
                time.sleep(0.1)
            shutil.rmtree(self.workdir, ignore_errors=True)
            self.workdir = None
        self.profile = None

    # -- the wire ------------------------------------------------------------------------------------

    def _s(self, path: str) -> str:
        if self.session is None:
            raise WebDriverError("no session (the browser is not started or already closed)")
        return f"/session/{self.session}{path}"

    def _request(self, method: str, path: str, body: Any = None, timeout: float | None = None) -> Any:
        url = f"http://127.0.0.1:{self.port}{path}"
        data = None if body is None and method != "POST" else json.dumps(body or {}).encode()
        req = urllib.request.Request(url, data=data, method=method)
        req.add_header("Content-Type", "application/json; charset=utf-8")
        try:
            with urllib.request.urlopen(req, timeout=timeout or self.command_timeout) as r:
                payload = r.read()
        except urllib.error.HTTPError as e:
            payload = e.read()
            try:
                v = json.loads(payload)["value"]
                err, msg = v.get("error"), v.get("message", "")
            except (ValueError, KeyError, TypeError, AttributeError):
                err, msg = None, payload[-2000:].decode("utf-8", "replace")
            raise WebDriverError(f"{method} {path}: HTTP {e.code} {err}: {msg}", err) from None
        except urllib.error.URLError as e:
            raise WebDriverError(f"{method} {path}: {e.reason}") from None
        return json.loads(payload)["value"]

    # -- commands ------------------------------------------------------------------------------------

    def open(self, url: str) -> None:
        """Navigate and wait for the page's load event (images included, except lazy ones)."""
        self._request("POST", self._s("/url"), {"url": url})

    @staticmethod
    def ref(element_id: str) -> dict:
        """An element id as a script argument."""
        return {ELEMENT_KEY: element_id}

    def script(self, js: str, *args: Any) -> Any:
        """Run `js` as a function body (W3C execute/sync; `arguments[i]` are `args`) and return its value.
        Elements in the value come back as element ids (str); pass an id back with `Browser.ref(id)`."""
        value = self._request("POST", self._s("/execute/sync"), {"script": js, "args": list(args)})
        return _unwrap(value)

    def find(self, css: str) -> str:
        """The first element matching a CSS selector, as an element id (WebDriverError if none)."""
        value = self._request("POST", self._s("/element"), {"using": "css selector", "value": css})
        return value[ELEMENT_KEY]

    def find_all(self, css: str) -> list[str]:
        value = self._request("POST", self._s("/elements"), {"using": "css selector", "value": css})
        return [v[ELEMENT_KEY] for v in value]

    def click(self, element_id: str) -> None:
        """A real click (W3C element click: scrolled into view, hit-tested, mouse events dispatched)."""
        self._request("POST", self._s(f"/element/{element_id}/click"), {})

    def text(self, element_id: str) -> str:
        """The element's rendered text (W3C Get Element Text: as displayed, whitespace collapsed)."""
        return self._request("GET", self._s(f"/element/{element_id}/text"))

    def attribute(self, element_id: str, name: str) -> str | None:
        return self._request("GET", self._s(f"/element/{element_id}/attribute/{name}"))

    def window_rect(self) -> dict:
        return self._request("GET", self._s("/window/rect"))

    def set_window_rect(self, width: int | None = None, height: int | None = None) -> dict:
        body = {k: v for k, v in (("width", width), ("height", height)) if v is not None}
        return self._request("POST", self._s("/window/rect"), body)

    def console(self) -> list[dict]:
        """The browser console entries since the last call (chromedriver's log extension):
        dicts with level (SEVERE, WARNING, INFO...), message and timestamp."""
        try:
            return self._request("POST", self._s("/se/log"), {"type": "browser"})
        except WebDriverError:
            return []

    def screenshot(self, path: str | os.PathLike, full_page: bool = True) -> Path:
        """Save a PNG of the viewport; with `full_page`, the window is first made as tall as the page
        (document.body.scrollHeight, at most MAX_SHOT_HEIGHT px) and restored afterwards."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        old = None
        if full_page:
            old = self.window_rect()
            # Window height = viewport + browser chrome (none in headless, but measured, not assumed).
            page_h, chrome_h = self.script(
                "return [Math.max(document.body.scrollHeight, document.documentElement.scrollHeight),"
                " window.outerHeight - window.innerHeight];"
            )
            height = min(int(page_h) + max(int(chrome_h), 0), MAX_SHOT_HEIGHT)
            self.set_window_rect(width=old["width"], height=max(height, 100))
            self.script("window.scrollTo(0, 0);")
        try:
            png = base64.b64decode(self._request("GET", self._s("/screenshot")))
        finally:
            if old is not None:
                self.set_window_rect(width=old["width"], height=old["height"])
        path.write_bytes(png)
        return path


def _unwrap(v: Any) -> Any:
    if isinstance(v, dict):
        if ELEMENT_KEY in v and len(v) == 1:
            return v[ELEMENT_KEY]
        return {k: _unwrap(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_unwrap(x) for x in v]
    return v


def main(argv: list[str] | None = None) -> int:
    """`python3 tests/browser/webdriver.py PAGE.html OUT.png [WIDTH HEIGHT]`: a screenshot of a page (the
    viewport, WIDTH x HEIGHT, default 1200 x 1500), as the picture of a report in docs/guide.md was taken."""
    import sys

    args = sys.argv[1:] if argv is None else argv
    if len(args) not in (2, 4):
        print(main.__doc__, file=sys.stderr)
        return 2
    width, height = (int(args[2]), int(args[3])) if len(args) == 4 else (1200, 1500)
    with Browser(width=width, height=height) as b:
        b.open(Path(args[0]).resolve().as_uri())
        b.screenshot(args[1], full_page=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
