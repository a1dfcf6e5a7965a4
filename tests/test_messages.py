"""pac_common.messages against the .msg files it mirrors: every constant has the value the
.msg file gives it, every field dictionary has exactly the message's fields, every topic's
type has its .msg file.  A field or constant added to (or renamed in) a .msg file without the
same change in messages.py fails here."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from pac_common import messages

pytestmark = pytest.mark.unit

MSG_DIR = Path(__file__).resolve().parents[1] / "src" / "pac_interfaces" / "msg"
LINE = re.compile(r"^\s*(?P<type>[\w/]+(?:\[\d*\])?)\s+(?P<name>\w+)\s*(?:=\s*(?P<value>\S+))?\s*$")


def parse_msg(typename: str) -> tuple[list[str], dict[str, int]]:
    """(field names in order, constants) of ``pac_interfaces/msg/<Name>``'s .msg file."""
    fields, constants = [], {}
    for raw in (MSG_DIR / f"{typename.rsplit('/', 1)[1]}.msg").read_text().splitlines():
        line = raw.split("#", 1)[0]
        if not line.strip():
            continue
        m = LINE.match(line)
        assert m, f"{typename}: cannot read {raw!r}"
        if m["value"] is None:
            fields.append(m["name"])
        else:
            constants[m["name"]] = int(m["value"])
    return fields, constants


#: The pac message types of the watched topics (the loop's, run_status, pantograph_truth).
PAC_TYPES = {t for t in messages.WATCHED_TOPICS.values() if t.startswith("pac_interfaces/")}


def test_every_topic_type_has_its_msg_file_and_every_msg_file_a_topic():
    assert {f"pac_interfaces/msg/{p.stem}" for p in MSG_DIR.glob("*.msg")} == PAC_TYPES
    assert set(messages.TOPICS.values()) <= PAC_TYPES


def test_constants_are_the_msg_files_constants():
    _, command = parse_msg(messages.ACTUATOR_COMMAND)
    assert {f"MODE_{k.upper()}": v for k, v in messages.MODES.items()} == command
    _, truth = parse_msg(messages.PLANT_TRUTH)
    assert truth == {
        "COMMAND_FRESH": messages.COMMAND_FRESH,
        "COMMAND_HELD": messages.COMMAND_HELD,
        "COMMAND_PASSIVE": messages.COMMAND_PASSIVE,
    }
    _, status = parse_msg(messages.RUN_STATUS)
    assert status == {"STATE_RUNNING": messages.RUN_RUNNING, "STATE_ENDED": messages.RUN_ENDED}
    _, estimate = parse_msg(messages.OBSERVER_ESTIMATE)
    assert estimate == {
        "STATUS_OK": messages.STATUS_OK,
        "STATUS_DIVERGED": messages.STATUS_DIVERGED,
        "STATUS_REINITIALISED": messages.STATUS_REINITIALISED,
        "STATUS_MEASUREMENT_REJECTED": messages.STATUS_MEASUREMENT_REJECTED,
    }
    _, measurement = parse_msg(messages.FRAME_MEASUREMENT)
    assert measurement == {}


def test_field_dictionaries_have_exactly_the_msg_fields():
    core = SimpleNamespace(
        tick=3,
        z1=0.1,
        z2=0.2,
        actuator_force=1.0,
        z=(0.0,) * 4,
        stiffness=1.0,
        contact_force=1.0,
        in_contact=True,
        u_applied=1.0,
        z_hat=(0.0,) * 4,
        theta_hat=(0.0,) * 3,
        stiffness_hat=1.0,
        contact_force_hat=1.0,
        innovation=(0.0,) * 2,
        u=1.0,
        u_unsaturated=1.0,
        force_reference=1.0,
        tracking_error=(0.0,) * 3,
        saturated=False,
        mode="active",
    )
    built = {
        messages.FRAME_MEASUREMENT: messages.measurement_fields(core, 0),
        messages.PLANT_TRUTH: messages.truth_fields(core, 0, applied_command_tick=2),
        messages.OBSERVER_ESTIMATE: messages.estimate_fields(core, 0),
        messages.ACTUATOR_COMMAND: messages.command_fields(core, 0),
        messages.RUN_STATUS: messages.run_status_fields(0, messages.RUN_RUNNING, 1.0, 0),
        messages.PANTOGRAPH_TRUTH: messages.pantograph_truth_fields(
            [
                SimpleNamespace(
                    **vars(core),
                    contact_position=1.0,
                    contact_uplift=0.0,
                    support_uplift=0.0,
                    controlled=True,
                )
            ],
            (0.0,),
            3,
            0,
        ),
    }
    assert set(built) == PAC_TYPES
    for typename, fields in built.items():
        assert list(fields) == parse_msg(typename)[0], typename
        assert list(fields["header"]) == ["stamp", "frame_id"]
