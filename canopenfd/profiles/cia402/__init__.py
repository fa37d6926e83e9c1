"""CiA 402 drives: the master's `Drive` helper over a remote node and a
simulated drive (`create_simulated_drive`) whose state machine and motion
model run in the C core. See docs/cia402.md."""

from .drive import Drive, DriveError, DriveFaultError, DriveTimeoutError
from .objects import DEVICE_TYPE_402, SUPPORTED_MODES_ALL, drive_od
from .simulated import create_simulated_drive
from .states import MODES, Command, DriveState, decode_state

__all__ = ["Drive", "DriveError", "DriveFaultError", "DriveTimeoutError", "DEVICE_TYPE_402",
           "SUPPORTED_MODES_ALL", "drive_od", "create_simulated_drive", "MODES", "Command",
           "DriveState", "decode_state"]
