"""An emulated mmWave SDK demo CLI on a pseudo-terminal: the radar's serial port for tests without hardware.

:class:`EmulatedRadarCli` opens a pseudo-terminal (``os.openpty``); the slave's name (:attr:`EmulatedRadarCli.port`)
is the "serial port" a client opens, and a thread on the master side answers as the SDK demo does
(mmWave SDK user's guide, "CLI"; TI's ``utils/cli/src/cli.c``): it echoes each line, writes ``Done``
for an accepted command, ``Error -1`` (after the handler's own ``Error: …`` line) for a refused one,
``'<cmd>' is not recognized as a CLI command`` for an unknown one, ``Skipped`` for a ``%`` comment,
and the prompt ``mmwDemo:/>`` after each. ``sensorStart`` is accepted only after the configuration
(``channelCfg``, ``adcCfg``, ``profileCfg``, ``chirpCfg``, ``frameCfg`` since the last ``flushCfg``),
as the demo requires; the refusal's first line is the emulator's own wording. A ``silent`` device
never answers; ``reply_delay`` delays every answer.

Room 4 (emulate); it imports nothing from :mod:`..live` — the client (``risloc_rt.measured.live.radar_cli``)
and this server share no code, only the protocol.
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty
from collections.abc import Iterable, Mapping
from typing import Any

from ..errors import MeasuredFormatError

__all__ = ["DEMO_COMMANDS", "EMULATED_PROMPT", "REQUIRED_BEFORE_START", "EmulatedRadarCli"]

#: The SDK demo's prompt.
EMULATED_PROMPT = "mmwDemo:/>"
#: Commands the emulated demo knows (mmWave SDK 3.x demo CLI; anything else is "not recognized").
DEMO_COMMANDS = frozenset({
    "sensorStart", "sensorStop", "flushCfg", "dfeDataOutputMode", "channelCfg", "adcCfg", "adcbufCfg",
    "profileCfg", "chirpCfg", "frameCfg", "advFrameCfg", "subFrameCfg", "lowPower", "guiMonitor", "cfarCfg",
    "multiObjBeamForming", "calibDcRangeSig", "clutterRemoval", "aoaFovCfg", "cfarFovCfg", "extendedMaxVelocity",
    "bpmCfg", "lvdsStreamCfg", "compRangeBiasAndRxChanPhase", "measureRangeBiasAndRxChanPhase", "CQRxSatMonitor",
    "CQSigImgMonitor", "analogMonitor", "calibData", "idlePowerCycle", "configDataPort", "queryDemoStatus",
    "version", "help",
})
#: Commands the demo needs before ``sensorStart`` (since the last ``flushCfg``).
REQUIRED_BEFORE_START = ("channelCfg", "adcCfg", "profileCfg", "chirpCfg", "frameCfg")


class EmulatedRadarCli:
    """The mmWave SDK demo's CLI on a pseudo-terminal, answered by a thread.

    Parameters
    ----------
    refuse : mapping of str to str, optional
        Command name → the handler's error line, for commands the device refuses
        (e.g. ``{"profileCfg": "Error: Invalid usage of the CLI command"}``); each answer ends with ``Error -1``.
    silent : bool, default False
        A device that reads but never answers (wrong port, demo not running).
    reply_delay : float, default 0
        Seconds before each answer [s].
    banner : bool, default True
        Write the prompt once when started, as the demo does after booting.
    line_ending : str, default "\\r\\n"
        What ends each reply line (the SDK's UART text mode writes ``\\r\\n``).

    Yields
    ------
    EmulatedRadarCli
        ``with EmulatedRadarCli() as radar:`` — ``radar.port`` is the device to open; on leaving, the
        thread is stopped and both ends of the pseudo-terminal closed.
    """

    def __init__(self, *, refuse: Mapping[str, str] | None = None, silent: bool = False, reply_delay: float = 0.0,
                 banner: bool = True, line_ending: str = "\r\n") -> None:
        self.refuse = dict(refuse or {})
        self.silent = bool(silent)
        self.reply_delay = float(reply_delay)
        if self.reply_delay < 0:
            raise MeasuredFormatError(f"reply_delay={reply_delay} s must be >= 0")
        self.banner = bool(banner)
        self.line_ending = line_ending
        self._master: int | None = None
        self._slave: int | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._lines: list[str] = []
        self._written = bytearray()
        self._configured: set[str] = set()
        self._started = False
        self._starts = 0
        self._error: BaseException | None = None
        self.port = ""

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "EmulatedRadarCli":
        """Open the pseudo-terminal (raw mode, no echo by the terminal itself) and start the thread.

        Returns
        -------
        EmulatedRadarCli
            self.
        """
        if self._thread is not None:
            return self
        master, slave = os.openpty()
        try:
            tty.setraw(slave)
            os.set_blocking(master, False)
            self.port = os.ttyname(slave)
            self._master, self._slave = master, slave
            self._stop.clear()
            if self.banner and not self.silent:
                self._write(EMULATED_PROMPT)          # before the thread: a client opening later finds it waiting
            self._thread = threading.Thread(target=self._serve, name="emulated-radar-cli", daemon=True)
            self._thread.start()
        except BaseException:
            os.close(master)
            os.close(slave)
            self._master = self._slave = None
            raise
        return self

    def close(self) -> None:
        """Stop the thread and close both ends (idempotent, safe on every path).

        Returns
        -------
        None
        """
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=5.0)
        for name in ("_master", "_slave"):
            fd = getattr(self, name)
            setattr(self, name, None)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def __enter__(self) -> "EmulatedRadarCli":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ------------------------------------------------------------------ state
    @property
    def started(self) -> bool:
        """True between an accepted ``sensorStart`` and the next ``sensorStop``."""
        with self._lock:
            return self._started

    @property
    def starts(self) -> int:
        """How many times ``sensorStart`` was accepted."""
        with self._lock:
            return self._starts

    @property
    def lines(self) -> tuple[str, ...]:
        """Every line received, in order, as read (line ending removed, blank lines dropped)."""
        with self._lock:
            return tuple(self._lines)

    @property
    def written(self) -> bytes:
        """Every byte the emulated device wrote (echoes, replies, prompts), for a test's own decoder."""
        with self._lock:
            return bytes(self._written)

    @property
    def error(self) -> BaseException | None:
        """An exception that ended the thread, or None."""
        return self._error

    def wait_for_lines(self, count: int, timeout: float = 5.0) -> bool:
        """Wait until ``count`` lines were received.

        Parameters
        ----------
        count : int
            Lines to wait for.
        timeout : float, default 5
            Longest wait [s].

        Returns
        -------
        bool
            True when they arrived in time.
        """
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if len(self.lines) >= count:
                return True
            time.sleep(0.005)
        return len(self.lines) >= count

    # ------------------------------------------------------------------ the device
    def _write(self, text: str) -> None:
        data = text.encode("ascii", errors="replace")
        with self._lock:
            self._written += data
        view = memoryview(data)
        while view and self._master is not None and not self._stop.is_set():
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                time.sleep(0.001)
                continue
            view = view[n:]

    def _serve(self) -> None:
        try:
            pending = bytearray()
            while not self._stop.is_set():
                ready, _, _ = select.select([self._master], [], [], 0.02)
                if not ready:
                    continue
                try:
                    chunk = os.read(self._master, 4096)
                except OSError:           # the client closed the slave: keep serving a later open
                    time.sleep(0.01)
                    continue
                pending += chunk
                for line in _take_lines(pending):
                    self._answer(line)
        except BaseException as exc:  # noqa: BLE001 - kept for the test to see, the thread must end quietly
            self._error = exc

    def _answer(self, line: str) -> None:
        with self._lock:
            self._lines.append(line)
        if self.silent:
            return
        if self.reply_delay:
            self._stop.wait(self.reply_delay)
        end = self.line_ending
        reply = self._reply(line)
        self._write(line + end + "".join(r + end for r in reply) + EMULATED_PROMPT)

    def _reply(self, line: str) -> list[str]:
        """The demo's answer lines to one command (echo and prompt written by the caller)."""
        if line.startswith("%"):
            return ["Skipped"]
        cmd = line.split()[0]
        if cmd not in DEMO_COMMANDS:
            return [f"'{cmd}' is not recognized as a CLI command"]
        if cmd in self.refuse:
            return [self.refuse[cmd], "Error -1"]
        with self._lock:
            if cmd == "flushCfg":
                self._configured.clear()
            elif cmd == "sensorStop":
                if not self._started:
                    return ["Ignored: Sensor is already stopped", "Done"]
                self._started = False
            elif cmd == "sensorStart":
                missing = [c for c in REQUIRED_BEFORE_START if c not in self._configured]
                if missing:
                    return [f"Error: the configuration is incomplete (missing {', '.join(missing)})", "Error -1"]
                if self._started:
                    return ["Ignored: Sensor is already started", "Done"]
                self._started = True
                self._starts += 1
            else:
                self._configured.add(cmd)
        return ["Done"]


def _take_lines(pending: bytearray) -> Iterable[str]:
    """Complete lines (``\\n`` or ``\\r`` ended) taken out of ``pending``, blank ones dropped."""
    out = []
    while True:
        cut = [i for i in (pending.find(b"\n"), pending.find(b"\r")) if i >= 0]
        if not cut:
            return out
        i = min(cut)
        line = bytes(pending[:i]).decode("ascii", errors="replace").strip()
        del pending[: i + 1]
        if line:
            out.append(line)
