"""What the tests of hostile arguments share: a refused command's one line."""

import pytest

from dfwb.cli import main


def refused(capsys, *argv):
    """The one line of stderr of a refused command (exit code 2)."""
    with pytest.raises(SystemExit) as stop:
        main(list(argv))
    err = capsys.readouterr().err
    assert stop.value.code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]
