"""The radar's CLI port: send an mmWave SDK ``.cfg`` line by line, start and stop the sensor.

The mmWave SDK demo (mmWave SDK user's guide, "CLI"; TI's ``utils/cli/src/cli.c``) speaks on the
"User/CLI" UART (the first of the board's two USB serial ports, 115200 baud): it echoes each line it
reads, runs the command and writes ``Done`` when the handler accepted it, ``Error <code>`` when it
refused it (handlers often print their own ``Error: …`` or ``Invalid usage of the CLI command`` line
first), ``'<cmd>' is not recognized as a CLI command`` for an unknown command and ``Skipped`` for a
``%`` comment, then its prompt ``mmwDemo:/>`` again. :class:`RadarCli` writes one line, reads until
the prompt comes back (or a timeout), strips the echo and judges the reply; every exchange is kept
in :attr:`RadarCli.transcript` for the caller's log.

``pyserial`` is imported only when a port is opened (:meth:`RadarCli.open`).
"""

from __future__ import annotations

import errno
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import MeasuredFormatError

__all__ = ["CLI_BAUDRATE", "CLI_MAX_LINE", "CLI_PROMPT", "CliExchange", "RadarCli", "RadarCliError", "config_lines", "is_accepted"]

#: The SDK demo's CLI prompt (mmWave SDK user's guide; ``cliPrompt`` of the demo's ``CLI_open``).
CLI_PROMPT = "mmwDemo:/>"
#: The CLI UART's baud rate in the SDK demos (mmWave SDK user's guide).
CLI_BAUDRATE = 115200
#: Longest line the demo's CLI reads (``cli.c``: a 256-byte command buffer, one byte for the terminating zero).
CLI_MAX_LINE = 255
#: What to check when the radar does not answer (appended to the timeout message).
_NO_ANSWER_HINT = ("check that this is the CLI (User/UART, usually the first /dev/ttyUSB or /dev/ttyACM of the board) "
                   "port and not the data port, that the SOP jumpers are in functional mode with the mmWave SDK "
                   "demo flashed, and the baud rate")


class RadarCliError(MeasuredFormatError):
    """The radar's CLI port cannot be opened, does not answer, or refused a command (one line, with the fix)."""


@dataclass(frozen=True)
class CliExchange:
    """One line sent to the radar and what came back.

    Parameters
    ----------
    sent : str
        The line as written (without the line ending).
    reply : str
        The radar's answer without the echo and the prompt, lines joined by ``\\n``.
    seconds : float
        From writing the line to the prompt (or the timeout) [s].
    answered : bool
        False when the prompt did not come back in time.
    """

    sent: str
    reply: str
    seconds: float
    answered: bool = True

    @property
    def accepted(self) -> bool:
        """True when the radar answered ``Done`` and no error (:func:`is_accepted`)."""
        return self.answered and is_accepted(self.reply)


def is_accepted(reply: str) -> bool:
    """Whether a CLI reply means the command was accepted.

    Parameters
    ----------
    reply : str
        The reply without echo and prompt.

    Returns
    -------
    bool
        True when a line reads ``Done`` and no line starts with ``Error`` or says the command is not
        recognised or was used wrongly (mmWave SDK ``cli.c``: ``Done`` / ``Error %d``).
    """
    lines = [ln.strip() for ln in reply.splitlines()]
    refused = any(ln.startswith("Error") or "is not recognized as a CLI command" in ln
                  or "Invalid usage" in ln for ln in lines)
    return "Done" in lines and not refused


def config_lines(source: str | Path | Iterable[str]) -> list[tuple[int, str]]:
    """The commands of a ``.cfg`` to send: ``(line number, line)``, comments (``%``) and blank lines skipped.

    Parameters
    ----------
    source : path, str or iterable of str
        A ``.cfg`` file, its text (a string with line breaks), or its lines.

    Returns
    -------
    list of (int, str)
        1-based line numbers of the file and the stripped command lines, in order.
    """
    if isinstance(source, str) and "\n" in source:
        lines: Iterable[str] = source.splitlines()
    elif isinstance(source, (str, Path)):
        path = Path(source)
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise RadarCliError(f"cannot read the config {path}: {exc.strerror}; give an mmWave SDK .cfg") from None
        lines = text.splitlines()
    else:
        lines = source
    out = []
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if line and not line.startswith("%"):
            out.append((number, line))
    return out


def _open_error(port: str, baudrate: int, exc: BaseException) -> RadarCliError:
    """The one-line error for a port that does not open, with the fix for its cause."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    if code == errno.ENOENT or "No such file" in text:
        return RadarCliError(f"radar CLI port {port} does not exist; plug the radar in and give its CLI port "
                             "(ls /dev/ttyUSB* /dev/ttyACM* /dev/serial/by-id/: the first of the board's two ports)")
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return RadarCliError(f"radar CLI port {port}: permission denied; add yourself to the dialout group "
                             "(sudo usermod -aG dialout $USER, then log in again)")
    if code in (errno.EBUSY, errno.EAGAIN) or "exclusively lock" in text or "busy" in text.lower():
        return RadarCliError(f"radar CLI port {port} is busy; close the program holding it (a terminal, "
                             "the mmWave visualizer, another risloc)")
    first = text.splitlines()[0] if text else repr(exc)
    return RadarCliError(f"cannot open the radar CLI port {port} at {baudrate} baud: {first}")


class RadarCli:
    """The mmWave SDK demo's CLI over a serial port, as a context manager.

    Parameters
    ----------
    port : str
        The CLI port's device (``/dev/ttyUSB0``, ``/dev/serial/by-id/…-if00``), or a pseudo-terminal.
    baudrate : int, default 115200
        The CLI UART's baud rate [bit/s].
    timeout : float, default 2.0
        Longest wait for the prompt after one line [s].
    start_timeout : float, default 10.0
        Longest wait after ``sensorStart`` (the radar calibrates first) [s].
    eol : str, default "\\n"
        Line ending written after each command.
    log : callable, optional
        Called with each :class:`CliExchange` as it completes.

    Yields
    ------
    RadarCli
        ``with RadarCli(port) as cli:`` opens the port; leaving with an exception sends ``sensorStop``
        (best effort) before closing.
    """

    def __init__(self, port: str, baudrate: int = CLI_BAUDRATE, timeout: float = 2.0, *, start_timeout: float = 10.0,
                 eol: str = "\n", log: Callable[[CliExchange], Any] | None = None) -> None:
        self.port = str(port)
        self.baudrate = int(baudrate)
        self.timeout = float(timeout)
        self.start_timeout = float(start_timeout)
        self.eol = eol
        self._log = log
        self._serial: Any = None
        self._transcript: list[CliExchange] = []

    # ------------------------------------------------------------------ port
    def open(self) -> "RadarCli":
        """Open the port (pyserial, 8N1, exclusive) and drop what the radar wrote before.

        Returns
        -------
        RadarCli
            self.

        Raises
        ------
        RadarCliError
            A missing port, a permission error (not in ``dialout``), a busy port, pyserial missing.
        """
        if self._serial is not None:
            return self
        try:
            import serial
        except ImportError:
            raise RadarCliError("pyserial is not installed; pip install pyserial==3.5") from None
        try:
            self._serial = serial.Serial(self.port, self.baudrate, timeout=0.02, write_timeout=self.timeout,
                                         exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise _open_error(self.port, self.baudrate, exc) from None
        try:
            self._serial.reset_input_buffer()
        except Exception:  # noqa: BLE001 - some pseudo-terminals do not flush; nothing to drop then
            pass
        return self

    def close(self) -> None:
        """Close the port (idempotent).

        Returns
        -------
        None
        """
        port, self._serial = self._serial, None
        if port is not None:
            try:
                port.close()
            except Exception:  # noqa: BLE001 - closing a vanished USB port must not hide the real error
                pass

    def __enter__(self) -> "RadarCli":
        return self.open()

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            if exc_type is not None:
                self.stop_best_effort()
        finally:
            self.close()

    @property
    def transcript(self) -> tuple[CliExchange, ...]:
        """Every exchange so far, in order (what was sent, what came back, how long it took [s])."""
        return tuple(self._transcript)

    def transcript_text(self) -> str:
        """The transcript as a log: ``> line`` for what was sent, ``< reply`` lines for the answers.

        Returns
        -------
        str
            One line per sent command and per reply line, ``(no answer within … s)`` for a timeout.
        """
        out = []
        for ex in self._transcript:
            out.append(f"> {ex.sent}")
            out += [f"< {ln}" for ln in ex.reply.splitlines()]
            if not ex.answered:
                out.append(f"(no answer within {ex.seconds:.3g} s)")
        return "\n".join(out) + ("\n" if out else "")

    # ------------------------------------------------------------------ exchange
    def _read_until_prompt(self, timeout: float) -> tuple[str, bool]:
        """Bytes up to the prompt (decoded, prompt removed) and whether the prompt came.

        A prompt with nothing before it is one the radar wrote before this line (after booting, or
        for an empty line) and is dropped: the SDK demo echoes every line before its prompt.
        """
        buf = bytearray()
        prompt = CLI_PROMPT.encode()
        deadline = time.monotonic() + timeout
        while True:
            chunk = self._serial.read(max(1, self._serial.in_waiting or 1))
            if chunk:
                buf += chunk
                if buf.strip() == prompt:     # a prompt left over from before this line (boot, Enter): not ours
                    buf.clear()
                elif buf.rstrip().endswith(prompt):
                    text = buf.decode("utf-8", errors="replace").rstrip()
                    return text[: -len(CLI_PROMPT)], True
            elif time.monotonic() >= deadline:
                return buf.decode("utf-8", errors="replace"), False

    @staticmethod
    def _strip_echo(text: str, line: str) -> str:
        """The reply lines without the echo of ``line`` and blank lines."""
        lines = [ln.strip() for ln in text.replace("\r", "\n").split("\n")]
        lines = [ln for ln in lines if ln]
        if lines and lines[0] == line.strip():
            lines = lines[1:]
        return "\n".join(lines)

    def exchange(self, line: str, *, timeout: float | None = None) -> CliExchange:
        """Write one line and read the answer up to the prompt; never raises for a refusal or a timeout.

        Parameters
        ----------
        line : str
            One CLI command (no line ending).
        timeout : float, optional
            Longest wait for the prompt [s]; default :attr:`timeout`.

        Returns
        -------
        CliExchange
            What was sent, the reply (echo and prompt stripped), the time taken [s], whether it answered.
        """
        if self._serial is None:
            raise RadarCliError(f"radar CLI port {self.port} is not open; use 'with RadarCli(port) as cli:'")
        wait = self.timeout if timeout is None else float(timeout)
        line = line.strip()
        t0 = time.monotonic()
        try:
            self._serial.write((line + self.eol).encode("ascii", errors="replace"))
            self._serial.flush()
            text, answered = self._read_until_prompt(wait)
        except OSError as exc:   # serial.SerialException is an OSError: the USB port went away
            raise RadarCliError(f"radar CLI port {self.port} failed while sending {line!r}: {exc}; check the "
                                "USB cable and that the port still exists") from None
        ex = CliExchange(sent=line, reply=self._strip_echo(text, line), seconds=time.monotonic() - t0,
                         answered=answered)
        self._transcript.append(ex)
        if self._log is not None:
            self._log(ex)
        return ex

    def _no_answer(self, ex: CliExchange, where: str = "") -> RadarCliError:
        got = f" (got {ex.reply[-80:]!r})" if ex.reply else ""
        return RadarCliError(f"{where}the radar on {self.port} did not answer {ex.sent!r} with the '{CLI_PROMPT}' "
                             f"prompt within {ex.seconds:.3g} s{got}; {_NO_ANSWER_HINT} ({self.baudrate} baud)")

    def send(self, line: str, *, timeout: float | None = None, check: bool = True) -> str:
        """Send one command and return the radar's reply.

        Parameters
        ----------
        line : str
            One CLI command.
        timeout : float, optional
            Longest wait for the prompt [s]; default :attr:`timeout`.
        check : bool, default True
            Raise when the radar refused the command (no ``Done``, or an error line).

        Returns
        -------
        str
            The reply without the echo and the prompt (e.g. ``"Done"``).

        Raises
        ------
        RadarCliError
            No prompt within the timeout (what to check), or a refusal with the radar's own text (``check``).
        """
        ex = self.exchange(line, timeout=timeout)
        if not ex.answered:
            raise self._no_answer(ex)
        if check and not ex.accepted:
            raise RadarCliError(f"the radar refused {ex.sent!r}: {_one_line(ex.reply)}")
        return ex.reply

    def send_config(self, source: str | Path | Iterable[str], progress: Callable[[int, int, str], Any] | None = None,
                    *, start: bool | None = None) -> tuple[CliExchange, ...]:
        """Send a ``.cfg`` one line at a time, each after the prompt of the one before.

        Parameters
        ----------
        source : path, str or iterable of str
            The ``.cfg`` file, its text or its lines; ``%`` comments and blank lines are not sent.
        progress : callable, optional
            ``progress(done, total, line)`` after each accepted line.
        start : bool, optional
            None sends the file as it is; False leaves out its ``sensorStart`` lines (the caller starts
            the sensor later with :meth:`sensor_start`); True also sends ``sensorStart`` when the file has none.

        Returns
        -------
        tuple of CliExchange
            The exchanges of this configuration.

        Raises
        ------
        RadarCliError
            The first refused line (the radar's text, the ``.cfg`` line number and the line) or a line
            without an answer; ``sensorStop`` has been sent (best effort) before it is raised. A line
            longer than the CLI reads (:data:`CLI_MAX_LINE`) is refused before anything is sent.
        """
        name = str(source) if isinstance(source, Path) or (isinstance(source, str) and "\n" not in source) \
            else "<config>"
        lines = config_lines(source)
        if start is False:
            lines = [(n, ln) for n, ln in lines if ln.split()[0] != "sensorStart"]
        elif start and not any(ln.split()[0] == "sensorStart" for _, ln in lines):
            lines.append((0, "sensorStart"))
        for number, line in lines:
            if len(line) + len(self.eol) > CLI_MAX_LINE:
                raise RadarCliError(f"{name}:{number}: {line.split()[0]} is {len(line)} characters long; the radar's "
                                    f"CLI reads at most {CLI_MAX_LINE} per line (mmWave SDK cli.c): shorten its "
                                    "numbers (fewer decimals)")
        done: list[CliExchange] = []
        try:
            for i, (number, line) in enumerate(lines):
                is_start = line.split()[0] == "sensorStart"
                ex = self.exchange(line, timeout=self.start_timeout if is_start else None)
                done.append(ex)
                where = f"{name}:{number}: " if number else f"{name}: "
                if not ex.answered:
                    raise self._no_answer(ex, where)
                if not ex.accepted:
                    raise RadarCliError(f"{where}the radar refused {line!r}: {_one_line(ex.reply)}; fix that line "
                                        "(mmWave SDK user's guide, CLI commands) and send the config again")
                if progress is not None:
                    progress(i + 1, len(lines), line)
        except BaseException:
            self.stop_best_effort()
            raise
        return tuple(done)

    def sensor_start(self) -> str:
        """Send ``sensorStart`` (waits up to :attr:`start_timeout` [s]: the radar calibrates first).

        Returns
        -------
        str
            The reply (``Done`` after the radar's debug lines).

        Raises
        ------
        RadarCliError
            Refused (e.g. a chirp outside the band gives ``Error -1``) or no answer; ``sensorStop`` sent.
        """
        try:
            return self.send("sensorStart", timeout=self.start_timeout)
        except BaseException:
            self.stop_best_effort()
            raise

    def sensor_stop(self) -> str:
        """Send ``sensorStop`` (a stopped sensor answers ``Ignored: Sensor is already stopped`` and ``Done``).

        Returns
        -------
        str
            The reply.

        Raises
        ------
        RadarCliError
            Refused or no answer.
        """
        return self.send("sensorStop")

    def stop_best_effort(self) -> bool:
        """Send ``sensorStop`` once (waiting at most 0.5 s), swallowing every error (cleanup on a failure path).

        Returns
        -------
        bool
            True when the radar answered ``Done``.
        """
        if self._serial is None:
            return False
        if self._transcript and self._transcript[-1].sent == "sensorStop":
            return self._transcript[-1].accepted      # just tried: a second try would only wait again
        try:
            return self.exchange("sensorStop", timeout=min(self.timeout, 0.5)).accepted
        except Exception:  # noqa: BLE001 - cleanup must not replace the error being raised
            return False


def _one_line(reply: str) -> str:
    """The radar's reply on one line (``' / '`` between its lines), or a note that it said nothing."""
    text = " / ".join(ln for ln in reply.splitlines() if ln.strip())
    return text if text else "no 'Done' and no error text"
