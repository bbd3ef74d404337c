"""Progress bars: a log off a terminal gets plain lines, never carriage returns or cursor moves."""

import io

from sim.progress import LineStream, progress_bar


class Pipe(io.StringIO):
    def isatty(self) -> bool:
        return False


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_off_a_terminal_a_bar_writes_plain_lines_and_a_transient_one_nothing(monkeypatch):
    log = Pipe()
    monkeypatch.setattr("sys.stderr", log)
    with progress_bar(total=3, desc="tasks", mininterval=0) as bar:
        for _ in range(3):
            bar.update(1)
    for _ in progress_bar(range(5), desc="domains", transient=True):
        pass
    for _ in progress_bar(range(5), desc="epochs", leave=False):
        pass
    text = log.getvalue()
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    assert lines and all(line.startswith("tasks:") for line in lines)
    assert lines[-1].startswith("tasks: 100%") and "3/3" in lines[-1]


def test_in_a_terminal_the_bar_is_tqdms_own(monkeypatch):
    screen = Terminal()
    monkeypatch.setattr("sys.stderr", screen)
    for _ in progress_bar(range(3), desc="domains", transient=True, mininterval=0):
        pass
    assert "\r" in screen.getvalue()  # redrawn in place


def test_the_line_stream_drops_blank_refreshes_and_cursor_moves():
    out = io.StringIO()
    stream = LineStream(out)
    stream.write("\r   \r")
    stream.write("\x1b[A\rtasks: 50%")
    assert out.getvalue() == "tasks: 50%\n"
