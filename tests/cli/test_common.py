"""The shared user-error exit of the cosim commands (cosim/cli/common.py)."""

from __future__ import annotations

from cosim.cli.common import EXIT_USER_ERROR, user_error_exit
from cosim.errors import UserError


def test_user_error_is_printed_verbatim_on_stderr_with_status_2(capsys):
    # square brackets that look like rich markup tags ("[nan ...]", "[fl]") must survive
    message = "component 'controller' failed at tick 3: output 'ref_x' = [nan 1.0]; omega[fl] [link]"
    exit_ = user_error_exit(UserError(message))
    assert exit_.exit_code == EXIT_USER_ERROR == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"error: {message}\n"
