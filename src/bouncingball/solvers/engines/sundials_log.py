"""The one place that keeps SUNDIALS' own text off the terminal: warnings become Python warnings, errors go.

SUNDIALS writes its warnings ("t + h = t on the next step", "root functions identically 0")
with fprintf to stderr, hundreds of thousands of them on an extreme scene, where no caller can
catch or filter them, and where they flood the log of a host that runs our FMU. Its logger reads
the file to write them to from SUNLOGGER_WARNING_FILENAME when a solver's SUNDIALS context is
created; scikit-sundae (checked on 1.2.0) creates it at a CVODE object's first solve or
init_step, and keeps it, with that file open, for the object's life. So each solver gets its own
file (on Linux one without a name, reached through /proc/self/fd), set in the environment around
its first call only, and read back after each call. Each cause (a message with its numbers taken
out) is reported once per solver, as a SundialsWarning.

SUNDIALS writes the file through a buffered C stream, which it flushes when the buffer is full
(4 KiB) or when the solver is freed, so messages reach the file, and the warnings, then. The stream
itself cannot be reached through scikit-sundae, and flushing every stream of the process instead
(fflush(NULL)) locks each one in turn: in a host that holds one locked while it waits (ecos keeps
a proxyfmu pipe in fgets for the whole run) the FMU's doStep waited for ever.

SUNDIALS' errors do not reach that file: scikit-sundae (checked on 1.2.0) replaces SUNDIALS' error
handler with its own, which prints "[CVode, Error: -2] At t = 0, too much accuracy requested." with
Python's print, to sys.stdout, beside the failed result whose message (CVMESSAGES) our SolverError
already carries. ErrorsOffStdout takes sys.stdout for the length of a solver call and passes on all
it received but that text.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
import warnings
import weakref

ENVIRONMENT_VARIABLE = "SUNLOGGER_WARNING_FILENAME"
_OWN_DESCRIPTORS = "/proc/self/fd"
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_MESSAGE = re.compile(r"^\[WARNING\]\[[^]]*\]\[[^]]*\]\[(?P<function>[^]]*)\] (?P<text>.*)$")


_NOTHING_TO_DO = contextlib.nullcontext()
_ERROR_TEXT = re.compile(r"\n?\[\w+, Error: -?\d+\] [^\n]*\n\n?")  # as scikit-sundae's _sunerr_handler prints it


class ErrorsOffStdout:
    """Around a scikit-sundae solver call: what it prints to sys.stdout, less SUNDIALS' error text, is passed on.

    Text another thread prints meanwhile is passed on too, after the call.
    """

    __slots__ = ("_buffer", "_previous")

    def __enter__(self) -> None:
        self._previous, self._buffer = sys.stdout, io.StringIO()
        sys.stdout = self._buffer

    def __exit__(self, *exception) -> None:
        sys.stdout = self._previous
        text = self._buffer.getvalue()
        if text:
            rest = _ERROR_TEXT.sub("", text)
            if rest and self._previous is not None:
                self._previous.write(rest)


class SundialsWarning(RuntimeWarning):
    """A warning SUNDIALS issued while integrating (its text, one per cause)."""


class SundialsLog:
    """The warnings file of one SUNDIALS solver.

    Wrap the solver's calls in ``capturing()``, then call ``report()`` to turn what it wrote
    into warnings.
    """

    def __init__(self) -> None:
        # Kept open to read back: seeking an open descriptor costs far less than a stat of the path.
        self._descriptor, self.path = tempfile.mkstemp(prefix="bouncingball-sundials-", suffix=".log")
        if os.path.isdir(_OWN_DESCRIPTORS):
            # Linux: SUNDIALS opens the file through our descriptor, so it needs no name at all and
            # nothing is left behind by a process that ends without finalising (a killed worker).
            os.remove(self.path)
            self.path = os.path.join(_OWN_DESCRIPTORS, str(self._descriptor))
        self._opened = False
        self._offset = 0
        self._causes: set[str] = set()
        self._remove = weakref.finalize(self, _remove, self._descriptor, self.path)

    def capturing(self):
        """Around a solver call: the first one makes SUNDIALS open this log's file."""
        # a solver makes one call per phase: once the file is open, the cheapest context there is
        return _NOTHING_TO_DO if self._opened else self._opening()

    @contextlib.contextmanager
    def _opening(self):
        previous = os.environ.get(ENVIRONMENT_VARIABLE)
        os.environ[ENVIRONMENT_VARIABLE] = self.path
        try:
            yield
        finally:
            self._opened = True
            if previous is None:
                del os.environ[ENVIRONMENT_VARIABLE]
            else:
                os.environ[ENVIRONMENT_VARIABLE] = previous

    def forget_causes(self) -> None:
        """Report every cause again from now on (a pooled solver's next run)."""
        self._causes.clear()

    def new_messages(self) -> list[str]:
        """The messages SUNDIALS has written out since the last call, one per new cause."""
        try:
            size = os.lseek(self._descriptor, 0, os.SEEK_END)
            if size <= self._offset:
                return []
            os.lseek(self._descriptor, self._offset, os.SEEK_SET)
            data = os.read(self._descriptor, size - self._offset)
        except OSError:
            return []
        complete = data.rfind(b"\n") + 1  # a line still being written is read next time
        self._offset += complete
        text = data[:complete].decode("utf-8", errors="replace")
        messages = []
        for line in text.splitlines():
            match = _MESSAGE.match(line)
            function, message = (match["function"], match["text"]) if match else ("", line)
            cause = function + _NUMBER.sub("#", message)
            if cause not in self._causes:
                self._causes.add(cause)
                messages.append(f"{function}: {message}" if function else message)
        return messages

    @property
    def descriptor(self) -> int:
        """The file's descriptor, open for the log's life."""
        return self._descriptor

    def size(self) -> int:
        """The file's size [bytes] now."""
        return os.lseek(self._descriptor, 0, os.SEEK_END)

    def new_warnings(self) -> list[SundialsWarning]:
        """Each new cause (new_messages) as a SundialsWarning, to issue or to pass on."""
        return [SundialsWarning(f"SUNDIALS {message}") for message in self.new_messages()]

    def report(self, stacklevel: int = 3) -> None:
        """Issue each new cause as a SundialsWarning."""
        for warning in self.new_warnings():
            warnings.warn(warning, stacklevel=stacklevel)


def _remove(descriptor: int, path: str) -> None:
    with contextlib.suppress(OSError):
        os.close(descriptor)
    if not path.startswith(_OWN_DESCRIPTORS):
        with contextlib.suppress(OSError):
            os.remove(path)
