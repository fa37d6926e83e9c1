"""CiA 402 drive control over `mem:` (issue 18 item 4): the master's `Drive`
helper against the simulated drive (its C state machine and motion model in
the runtime thread), on classic (SDO) and fd (USDO) lines: every power
transition, each mode, the errors (a drive that never leaves Switch on
disabled, a fault mid-move: exception, Fault state, the line usable after),
and the bytes on the bus (SDO controlword writes, PDO mapping downloads, the
cyclic RPDO/TPDO exchange, the fault's EMCY)."""

from __future__ import annotations

import pathlib
import subprocess
import sys
import threading

import pytest
from helpers import NEUTRAL_CWD, Recorder, package_env, scaled

from canopenfd import ConfigurationError
from canopenfd.errors import TransferAbortError
from canopenfd.profiles.cia402 import (DEVICE_TYPE_402, Drive, DriveError, DriveFaultError,
                                       DriveState, DriveTimeoutError, create_simulated_drive,
                                       decode_state, drive_od)

NODE = 5


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


class Rig:
    """Simulated drive node 5, the master's line and `Drive`, a monitor."""

    def __init__(self, net, bus_name, mode, **sim_options):
        self.mode = mode
        self.sim = create_simulated_drive(net.open_line(bus_name, mode=mode), NODE,
                                          **sim_options)
        self.frames = Recorder()
        net.open_line(bus_name, mode=mode, monitor=True).on_frame(self.frames)
        self.line = net.open_line(bus_name, mode=mode)
        self.node = self.line.add_node(NODE, od=drive_od(mode))
        self.drive = Drive(self.node, timeout=scaled(2))

    def frames_on(self, can_id, start=0):
        return [f for f in self.frames.snapshot()[start:] if f.id == can_id and not f.rtr]

    def wait_frames(self, can_id, count, start=0, timeout=2.0):
        def enough(_calls):
            got = self.frames_on(can_id, start)
            return got if len(got) >= count else None
        return self.frames.wait_for(enough, timeout, f"{count} frames on 0x{can_id:X}")


@pytest.fixture
def rig(net, bus_name, mode):
    return Rig(net, bus_name, mode)


def test_statusword_decoding():
    assert decode_state(0x0250) is DriveState.SWITCH_ON_DISABLED
    assert decode_state(0x0231) is DriveState.READY_TO_SWITCH_ON
    assert decode_state(0x0233) is DriveState.SWITCHED_ON
    assert decode_state(0x1637) is DriveState.OPERATION_ENABLED
    assert decode_state(0x0017) is DriveState.QUICK_STOP_ACTIVE
    assert decode_state(0x001F) is DriveState.FAULT_REACTION_ACTIVE
    assert decode_state(0x0008) is DriveState.FAULT
    assert decode_state(0x0000) is DriveState.NOT_READY_TO_SWITCH_ON
    assert decode_state(0x0041) is DriveState.UNKNOWN


def test_every_power_transition(rig):
    d = rig.drive
    assert rig.node.read((0x1000, 1 if rig.mode == "fd" else 0)) == DEVICE_TYPE_402
    assert d.state is DriveState.SWITCH_ON_DISABLED
    d.shutdown()
    assert d.state is DriveState.READY_TO_SWITCH_ON
    d.switch_on()
    assert d.state is DriveState.SWITCHED_ON
    d.enable()
    assert d.state is DriveState.OPERATION_ENABLED
    d.switch_on()                          # disable operation
    assert d.state is DriveState.SWITCHED_ON
    d.shutdown()
    d.disable_voltage()
    assert d.state is DriveState.SWITCH_ON_DISABLED
    d.enable()
    d.quick_stop()
    assert d.state is DriveState.QUICK_STOP_ACTIVE
    d.enable()                             # back from quick stop
    assert d.state is DriveState.OPERATION_ENABLED
    d.shutdown()
    d.quick_stop()                         # outside Operation enabled: voltage off
    assert d.state is DriveState.SWITCH_ON_DISABLED


def test_enable_sequence_bytes_classic(net, bus_name):
    rig = Rig(net, bus_name, "classic")
    start = len(rig.frames)
    rig.drive.enable()
    enabled = bytes([0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0, 0])   # 0x6041 upload: 0x0237
    # the monitor hears the last upload after enable() returned: wait for it
    rig.frames.wait_for(lambda _calls: any(bytes(f.data) == enabled for f in
                                           rig.frames_on(0x580 + NODE, start)),
                        2.0, "the upload of 0x6041 = 0x0237")
    requests = [bytes(f.data) for f in rig.frames_on(0x600 + NODE, start)
                if bytes(f.data)[:4] == bytes([0x2B, 0x40, 0x60, 0x00])]
    # expedited 2-byte downloads to 0x6040: shutdown, switch on, enable operation
    assert requests == [bytes([0x2B, 0x40, 0x60, 0, cw, 0, 0, 0]) for cw in (6, 7, 0x0F)]


def test_profile_position(rig):
    d = rig.drive
    d.set_mode("profile_position")
    assert d.mode == "profile_position"
    d.enable()
    d.move_to(500, velocity=5000, acceleration=100000, deceleration=100000)
    assert d.position == 500
    assert d.velocity == 0
    d.move_to(-200, relative=True)
    assert d.position == 300
    d.move_to(1000, velocity=1000, wait=False)
    assert d.statusword & 0x0400 == 0      # not there yet
    with pytest.raises(DriveTimeoutError, match="target reached"):
        d.move_to(100000, velocity=100, timeout=scaled(0.2))


def test_profile_velocity_and_homing(rig):
    d = rig.drive
    d.set_mode("pv")
    d.enable()
    d.set_velocity(800, acceleration=100000, wait=True)
    assert d.velocity == 800
    assert d.position > 0
    d.home(method=35)
    assert d.position == 0
    assert d.statusword & 0x1400 == 0x1400
    assert d.mode == "homing"


def test_fault_mid_move(rig):
    d = rig.drive
    d.set_mode("pp")
    d.enable()
    start = len(rig.frames)
    timer = threading.Timer(0.1, rig.sim.drive_simulation.fault, (0x7121,))
    timer.start()
    try:
        with pytest.raises(DriveFaultError, match=r"node 5: FAULT.*move_to\(100000\).*0x7121") \
                as caught:
            d.move_to(100000, velocity=1000, timeout=scaled(3))
    finally:
        timer.join()
    assert caught.value.code == 0x7121
    d.wait_for_state(DriveState.FAULT)
    assert d.error_code == 0x7121
    emcy = rig.wait_frames(0x80 + NODE, 1, start)[0]
    assert bytes(emcy.data)[:3] == bytes([0x21, 0x71, 0x21])   # code, register: profile
    with pytest.raises(DriveFaultError, match="enable"):
        d.enable()
    d.fault_reset()
    assert d.state is DriveState.SWITCH_ON_DISABLED
    assert d.error_code == 0
    d.enable()                             # the line and the drive carry on
    d.move_to(d.position + 10)


def test_never_leaves_switch_on_disabled(net, bus_name, mode):
    """A drive whose statusword stays at Switch on disabled (no simulation):
    enable() times out naming node, wanted and reached states; the line works on."""
    od = drive_od(mode)
    od.get_variable(0x6041, 0).default = 0x0240
    net.open_line(bus_name, mode=mode).create_local_node(NODE, od=od)
    line = net.open_line(bus_name, mode=mode)
    d = Drive(line.add_node(NODE))
    with pytest.raises(DriveTimeoutError,
                       match="drive node 5: enable.*wanted OPERATION ENABLED, state reached "
                             "SWITCH ON DISABLED") as caught:
        d.enable(timeout=scaled(0.3))
    assert caught.value.reached is DriveState.SWITCH_ON_DISABLED
    assert d.read(0x6041) == 0x0240        # the line still answers


def test_mode_errors(net, bus_name):
    rig = Rig(net, bus_name, "classic", supported_modes=0x1A5)   # no CST
    d = rig.drive
    with pytest.raises(ConfigurationError, match="unknown mode of operation 'bogus'"):
        d.set_mode("bogus")
    with pytest.raises(TransferAbortError) as caught:
        d.set_mode("cst")
    assert caught.value.code == 0x06090030 and caught.value.index == 0x6060
    d.enable()
    with pytest.raises(DriveError, match="needs mode profile_position"):
        d.move_to(10)
    with pytest.raises(ConfigurationError, match="tick_ms"):
        rig.sim.drive_simulation.start(0)
    with pytest.raises(ConfigurationError, match="error code"):
        rig.sim.drive_simulation.fault(0)


def test_start_without_the_objects_names_one(net, bus_name):
    from canopenfd.od import demo_od
    node = net.open_line(bus_name, mode="classic").create_local_node(NODE, od=demo_od("classic"))
    with pytest.raises(Exception, match="needs object 0x603F:00"):
        node.drive_simulation.start(1.0)


def test_setup_pdos_bytes_classic(net, bus_name):
    rig = Rig(net, bus_name, "classic")
    start = len(rig.frames)
    rig.drive.setup_pdos("pp")
    expected = [
        # RPDO2 mapping: controlword (16 bits), target position (32 bits), count 2
        bytes([0x23, 0x01, 0x16, 1, 0x10, 0, 0x40, 0x60]),
        bytes([0x23, 0x01, 0x16, 2, 0x20, 0, 0x7A, 0x60]),
        bytes([0x2F, 0x01, 0x16, 0, 2, 0, 0, 0]),
        # TPDO2: statusword, position actual
        bytes([0x23, 0x01, 0x1A, 2, 0x20, 0, 0x64, 0x60])]
    # the monitor may hear the last requests after setup_pdos returned: wait for them
    rig.frames.wait_for(lambda _calls: all(
        request in [bytes(f.data) for f in rig.frames_on(0x600 + NODE, start)]
        for request in expected), 2.0, "the mapping requests")
    assert rig.node.read((0x1A01, 1)) == 0x60410010


def test_cyclic_synchronous_position(rig):
    d = rig.drive
    cyc = d.cyclic("csp", period=0.005)
    try:
        d.enable()
        for step in range(1, 6):
            cyc.target = step * 100
            rig.frames.wait_for(lambda _c, v=step * 100: d.position == v, 2.0,
                                f"position {step * 100}")
        assert cyc.wait_actual() == 500
    finally:
        d.stop_cyclic()
    rpdo_id, tpdo_id = (0x305, 0x285) if rig.mode == "classic" else (0x205, 0x185)
    if rig.mode == "classic":
        # controlword 0x000F, target position 500 / statusword 0x1237, position 500
        rpdo, tpdo = bytes([0x0F, 0, 0xF4, 0x01, 0, 0]), bytes([0x37, 0x12, 0xF4, 0x01, 0, 0])
    else:
        # controlword, mode 8, target position (then target velocity and torque) /
        # statusword, mode display 8, position 500 (then velocity, torque, error code)
        rpdo = bytes([0x0F, 0, 8, 0xF4, 0x01, 0, 0])
        tpdo = bytes([0x37, 0x12, 8, 0xF4, 0x01, 0, 0])
    # the monitor may hear them after the master's line did: wait for both
    rig.frames.wait_for(lambda _calls: any(bytes(f.data).startswith(rpdo)
                                           for f in rig.frames_on(rpdo_id)) and
                        any(bytes(f.data).startswith(tpdo) for f in rig.frames_on(tpdo_id)),
                        2.0, "the RPDO with target 500 and the TPDO with position 500")
    assert d.state is DriveState.OPERATION_ENABLED


def test_cyclic_refuses_a_profile_mode(rig):
    with pytest.raises(ConfigurationError, match="not cyclic synchronous"):
        rig.drive.cyclic("pp")


def test_event_tpdo1_carries_each_new_statusword(rig):
    """The drive's default TPDO1 (statusword, type 255) goes out at each change."""
    rig.node.start()
    rig.sim.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    start = len(rig.frames)
    rig.drive.enable()

    def words(_calls):
        got = [bytes(f.data)[:2] for f in rig.frames_on(0x180 + NODE, start)]
        wanted = [bytes([sw, 0x02]) for sw in (0x31, 0x33, 0x37)]
        return got if [w for w in got if w in wanted] == wanted else None
    rig.frames.wait_for(words, 2.0, "TPDO1 with 0x0231, 0x0233, 0x0237")


@pytest.mark.parametrize("args", [(), ("--fd",)])
def test_the_example_runs(args):
    example = pathlib.Path(__file__).resolve().parent.parent / "examples" / "cia402_drive.py"
    done = subprocess.run([sys.executable, str(example), *args], cwd=NEUTRAL_CWD,
                          env=package_env(), capture_output=True, text=True,
                          timeout=scaled(120))
    assert done.returncode == 0, done.stderr
    for line in ("drive state: SWITCH ON DISABLED", "drive state: OPERATION ENABLED",
                 "profile position: at 2000",
                 "cyclic synchronous position: at 3000 after 50 targets",
                 "drive state: READY TO SWITCH ON",
                 "refused: drive node 5: move_to(0) needs mode profile_position"):
        assert line in done.stdout, done.stdout
