"""The C stack's enums and constants as Python enums, built from the binding.

cffi knows every enum of the cdef (the headers' `/* cffi:begin */` blocks):
a named enum's members through `ffi.typeof(...)`, an anonymous one's as
`lib.CO_...` names. Each enum here takes its members from there, named as in
C without the prefix (CO_COMM_BUS_OFF -> CommEvent.BUS_OFF), so a value
changed in a header is the value Python uses, and a member renamed or removed
in C is gone here too. tests/test_c_constants.py compares every enum with the
headers and checks that each member the package uses exists in C.

The one enum the cdef lacks (co_guard_event_t) is listed in `_NOT_IN_CDEF`,
checked against its header by the same test.

mypy does not read this file: it reads `constants.pyi`, the same enums written
out as classes by tests/gen_constants_stub.py from what this module built
(tests/test_typing.py regenerates it and fails when the checked-in one differs).
Hand-written code (the NMT enums' parse/label/target) lives in `c_enums`, where
mypy checks it; keep this file to the calls that build enums.
"""

from __future__ import annotations

import enum
import functools
from typing import Dict, Tuple

from .c_enums import C_ENUMS, NmtCommandBase, NmtStateBase, c_enum, c_members

__all__ = [
    "AbortCode", "CommEvent", "CommandKind", "Driver", "EmcyStatus", "ErrorBit",
    "ErrorRegister", "EventKind", "FrameFlag",
    "GuardEventCode", "HeartbeatEvent", "Indicate", "LssRequest", "LssStatus", "Mode",
    "NmtCommand", "NmtState", "FlymaAction", "FlymaEvent", "FlymaState",
    "GatewayEvent", "GatewayRouteKind",
    "OdOrigin", "ParameterGroup", "RtStatus", "SleepAction", "SleepCause", "SleepEvent",
    "SleepPhase", "StoreStatus", "BootError", "BootEvent", "BootStep", "ManagerEventCode",
    "ManagerPhase", "SlaveStatus", "C_ENUMS", "c_members",
    "LedPattern", "LedWhich", "LedCause", "SrdoState", "SrdoViolation",
    "RedundancyEvent",
]


# Each enum is made in this module (its __module__, so it pickles).
_c_enum = functools.partial(c_enum, module=__name__)


# ---------------------------------------------------------------- the runtime
EventKind = _c_enum("EventKind", "CO_EV_", "co_rt_event_kind_t",
                    doc="Kinds of the events the runtime posts (co_rt_event_kind_t).")
CommandKind = _c_enum("CommandKind", "CO_CMD_", "co_rt_command_kind_t",
                      doc="Commands of the runtime's mailbox (co_rt_command_kind_t).")
RtStatus = _c_enum("RtStatus", "CO_RT_", "co_rt_status_t",
                   doc="Status codes of the runtime's calls (co_rt_status_t; errors < 0).")
Driver = _c_enum("Driver", "CO_DRIVER_", "co_rt_driver_t",
                 doc="Drivers a line can run on (co_rt_driver_t).")
Indicate = _c_enum("Indicate", "CO_RT_INDICATE_",
                   doc="Kinds of object dictionary requests answered by the application.")

# ---------------------------------------------------------------- lines and frames
Mode = _c_enum("Mode", "CO_MODE_", "co_mode_t", doc="Line modes (co_mode_t).")
CommEvent = _c_enum("CommEvent", "CO_COMM_", "co_comm_event_t",
                    doc="Communication-state events of a line (co_comm_event_t).")
FrameFlag = _c_enum("FrameFlag", "CO_FRAME_", exclude=("MAX_DATA", "CLASSIC_MAX"),
                    doc="Flag bits of co_frame_t.flags.")

# ---------------------------------------------------------------- NMT and heartbeat
NmtState = _c_enum(
    "NmtState", "CO_NMT_", "co_nmt_state_t", base=NmtStateBase,
    doc="NMT state of a node, as carried by its heartbeat (CiA 301); UNKNOWN: never "
        "heard of (remote nodes only). Compares equal to its python-canopen names.")
NmtCommand = _c_enum("NmtCommand", "CO_NMT_CMD_", "co_nmt_command_t", base=NmtCommandBase,
                     doc="NMT command specifiers (CiA 301).")
NmtCommand.states = NmtState   # what NmtCommand.target answers in
HeartbeatEvent = _c_enum("HeartbeatEvent", "CO_HB_", "co_hb_event_t",
                         doc="What the heartbeat consumer reports of a node (co_hb_event_t).")

# ---------------------------------------------------------------- object dictionary
AbortCode = _c_enum("AbortCode", "CO_ABORT_", "co_abort_t",
                    doc="CiA 301 SDO abort codes (co_abort_t).")
ParameterGroup = _c_enum("ParameterGroup", "CO_GROUP_", "enum co_od_group",
                         doc="Parameter groups of 0x1010 / 0x1011 (bit masks).")
OdOrigin = _c_enum("OdOrigin", "CO_ORIGIN_", "co_od_origin_t",
                   doc="Who wrote an object dictionary entry (co_od_origin_t).")
StoreStatus = _c_enum("StoreStatus", "CO_STORE_", "co_store_status_t",
                      doc="What a parameter load found in the store (co_store_status_t).")

# ---------------------------------------------------------------- EMCY
EmcyStatus = _c_enum("EmcyStatus", "CO_EMCY_STATUS_",
                     doc="Bits of the FD EMCY's status byte (priority mask and flags).")
ErrorRegister = _c_enum("ErrorRegister", "CO_EMCY_ER_",
                        doc="Bits of the error register 0x1001 (CiA 301 classes).")
ErrorBit = _c_enum("ErrorBit", "CO_ERRORS_BIT_",
                   doc="Error-status bits of the errors the stack detects (co_errors.h).")

# ---------------------------------------------------------------- LSS
LssRequest = _c_enum("LssRequest", "CO_LSS_REQ_", "co_lss_request_t",
                     doc="Requests of the LSS master (co_lss_request_t).")
LssStatus = _c_enum("LssStatus", "CO_LSS_", "co_lss_status_t",
                    doc="How an LSS master request ended (co_lss_status_t).")
# ---------------------------------------------------------------- sleep and wake-up
SleepPhase = _c_enum("SleepPhase", "CO_SLEEP_", "co_sleep_phase_t",
                     doc="Phases of sleep and wake-up (co_sleep_phase_t, CiA 320).")
SleepEvent = _c_enum("SleepEvent", "CO_SLEEP_EV_", "co_sleep_event_t",
                     doc="What the sleep service reports (co_sleep_event_t).")
SleepCause = _c_enum("SleepCause", "CO_SLEEP_BY_", "co_sleep_cause_t",
                     doc="What woke a node (co_sleep_cause_t).")
SleepAction = _c_enum("SleepAction", "CO_RT_SLEEP_", "co_rt_sleep_action_t",
                      doc="What the application asks of the sleep service (co_rt_sleep_action_t).")

# ---------------------------------------------------------------- SRDO (CiA 304)
SrdoState = _c_enum("SrdoState", "CO_SRDO_", "co_srdo_state_t",
                    doc="What an SRDO does now (co_srdo_state_t).")
SrdoViolation = _c_enum("SrdoViolation", "CO_SRDO_", "co_srdo_violation_t",
                        doc="Why an SRDO entered the safe state (co_srdo_violation_t).")

# ---------------------------------------------------------------- flying master
FlymaState = _c_enum("FlymaState", "CO_FLYMA_", "co_flyma_state_t",
                     doc="States of the flying-master negotiation (co_flyma_state_t, CiA 302-2).")
FlymaEvent = _c_enum("FlymaEvent", "CO_FLYMA_EV_", "co_flyma_event_t",
                     doc="What the flying master reports (co_flyma_event_t).")
FlymaAction = _c_enum("FlymaAction", "CO_RT_FLYMA_", "co_rt_flyma_action_t",
                      doc="What the application asks of the flying master.")
# ---------------------------------------------------------------- bus redundancy
RedundancyEvent = _c_enum("RedundancyEvent", "CO_RDN_EV_", "co_rdn_event_t",
                          doc="What bus redundancy reports (co_rdn_event_t).")
# ---------------------------------------------------------------- gateway between lines
GatewayRouteKind = _c_enum("GatewayRouteKind", "CO_GATEWAY_", "co_gateway_route_kind_t",
                           doc="How a network is reached (co_gateway_route_kind_t).")
GatewayEvent = _c_enum("GatewayEvent", "CO_GATEWAY_EV_", "co_gateway_event_t",
                       doc="What the gateway reports (co_gateway_event_t).")
# ---------------------------------------------------------------- LED indicators (CiA 303-3)
LedPattern = _c_enum("LedPattern", "CO_LED_", "co_led_pattern_t",
                     doc="What a CiA 303-3 LED shows (co_led_pattern_t).")
LedWhich = _c_enum("LedWhich", "CO_LED_", "co_led_which_t",
                   doc="The run (green) and error (red) LEDs (co_led_which_t).")
LedCause = _c_enum("LedCause", "CO_LED_CAUSE_", "co_led_cause_t",
                   doc="What the error LED shows, one bit each (co_led_cause_t).")

# ---------------------------------------------------------------- CiA 302-2 network manager
BootError = _c_enum("BootError", "CO_BOOT_", "co_boot_error_t",
                    doc="Result of a boot-slave process: OK or the CiA 302-2 error letter "
                        "(value = the letter's ASCII code).")
BootStep = _c_enum("BootStep", "CO_BOOT_STEP_", "co_boot_step_t",
                   doc="Steps of a boot-slave process (co_boot_step_t).")
BootEvent = _c_enum("BootEvent", "CO_BOOT_EV_", "co_boot_event_t",
                    doc="Reports of a boot-slave process (co_boot_event_t).")
ManagerEventCode = _c_enum("ManagerEventCode", "CO_MANAGER_EV_", "co_manager_event_t",
                           doc="What the network manager reports (co_manager_event_t).")
ManagerPhase = _c_enum("ManagerPhase", "CO_MANAGER_", "co_manager_phase_t",
                       doc="Phase of the network start-up (co_manager_phase_t).")
SlaveStatus = _c_enum("SlaveStatus", "CO_MANAGER_SLAVE_", "co_manager_slave_status_t",
                      doc="Where a slave of the network list is (co_manager_slave_status_t).")

# ---------------------------------------------------------------- not in the cdef
# C enums the binding does not carry (they are outside the headers' cffi
# blocks): written out here, checked against the header by
# tests/test_c_constants.py. Once the enum moves into its header's cffi block,
# build it with _c_enum like the others.
_NOT_IN_CDEF: Dict[str, Tuple[str, Dict[str, int]]] = {
    "GuardEventCode": ("co_guard_event_t / CO_GUARD_", {
        "STARTED": 1, "STATE_CHANGED": 2, "LOST": 3, "RESUMED": 4, "TOGGLE_ERROR": 5,
        "UNEXPECTED_STATE": 6}),
}

GuardEventCode = enum.IntEnum(
    "GuardEventCode", list(_NOT_IN_CDEF["GuardEventCode"][1].items()), module=__name__,
    qualname="GuardEventCode")
GuardEventCode.__doc__ = "What node guarding reports of a guarded node (co_guard_event_t)."
