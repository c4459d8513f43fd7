"""The Franka Control Interface served from a MuJoCo simulation: one client on the robot's TCP
service port, the 1 kHz UDP state/command exchange, the Franka Hand on its own port.

One thread runs everything (sockets polled between physics steps), so a run in lockstep depends
on the commands only. `lockstep`: during a motion each state waits for its command (up to
`command_timeout` of wall time), which is what tests and machines that cannot hold 1 kHz need;
otherwise (`realtime`) the loop keeps wall-clock 1 kHz and a command that misses its cycle is
counted lost, as the robot counts it.
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
import struct
import time
from dataclasses import dataclass, field

import numpy as np

from mjkdl.errors import MjkdlError, SpecError
from mjkdl.viewer.display import NoDisplayError, require_display
from mjkdl.viewer.window import Window

from . import wire
from .arm import DT, LOST_CYCLES_LIMIT, SimulatedArm
from .gripper import SimulatedHand
from .limits import MODELS
from .model_library import ModelLibraryError, model_library
from .reality import Reality, reality_from
from .scene import franka_scene

log = logging.getLogger("mjkdl.hw.franka_sim")

CONNECT_REPLY = struct.Struct("<BH")  # status, server version
GRIPPER_CONNECT_REPLY = struct.Struct("<HH")
GRIPPER_STATE_EVERY = 10  # cycles: the hand streams its state at 100 Hz
# Lockstep, a motion's client not answering yet: states after the first few come this slowly.
FIRST_COMMAND_FAST_CYCLES = 2
FIRST_COMMAND_WAIT = 0.1  # s


class AddressInUseError(MjkdlError, OSError):
    """The robot's ports at the address asked for cannot be served."""


@dataclass
class _Peer:
    sock: socket.socket
    address: tuple[str, int]
    buffer: bytearray = field(default_factory=bytearray)
    udp: tuple[str, int] | None = None  # where states go, once connected
    protocol: wire.Protocol | None = None
    is_gripper: bool = False  # came in on the hand's port


class FrankaSimServer:
    """A simulated Franka arm (and hand) at `host`, speaking protocols 10 and 5; `scene`: what
    it shares its world with (`scene.SCENES`: "pick", or "empty" for hardware in the loop);
    `reality`: how its arm differs from the nominal simulation (`reality.Reality`, a preset's
    name or a JSON file; None: not at all)."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        model: str = "panda",
        lockstep: bool = True,
        viewer: bool = False,
        command_timeout: float = 1.0,
        robot_port: int = wire.ROBOT_PORT,
        gripper_port: int = wire.GRIPPER_PORT,
        scene: str = "pick",
        reality: str | Reality | None = None,
    ) -> None:
        if model not in MODELS:
            raise SpecError(f"model {model!r}: the simulator knows {sorted(MODELS)}")
        spec = franka_scene(scene)  # a bad name fails before the ports are taken
        the_reality = reality_from(reality)
        if viewer:
            try:
                require_display()
            except NoDisplayError as err:
                raise NoDisplayError(f"--viewer: {err}; or leave --viewer out") from err
        self.host = host
        self.scene = scene
        self.lockstep = lockstep
        self.command_timeout = command_timeout
        # the ports first: a taken address fails before the scene is built
        self._robot_listener: socket.socket | None = self._listen(robot_port)
        self._robot_port = self._robot_listener.getsockname()[1]
        try:
            self._gripper_listener = self._listen(gripper_port)
        except AddressInUseError:
            self._robot_listener.close()
            raise
        self.arm = SimulatedArm(spec, MODELS[model], the_reality)
        self.hand = SimulatedHand(self.arm.env)
        self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._udp.bind((host, 0))
        self._udp.setblocking(False)
        self.robot: _Peer | None = None
        self.gripper: _Peer | None = None
        self._pending: list[_Peer] = []  # accepted, not yet connected
        self._state = np.zeros(1, dtype=wire.PROTOCOL_10.state)
        self.message_id = 0
        self._motion_id: int | None = None
        self._gripper_job_ids: int | None = None
        self._viewer: Window | None = None
        if viewer:
            self._viewer = self._open_viewer()
        self._running = True
        self._sent_moving = False  # the last state sent showed a motion running
        self._answering = False  # the running motion's client has sent a command
        self._motion_started = 0.0  # perf_counter at the Move
        self._waiting_cycles = 0  # cycles since the Move without a command (lockstep)

    def _listen(self, port: int) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((self.host, port))
        except OSError as err:
            sock.close()
            raise AddressInUseError(
                err.errno,
                f"cannot listen on {self.host}:{port} ({err.strerror}): another simulator or "
                "robot driver holds it, or the address is not this machine's; stop the other or "
                "give another --host (any 127.x.y.z works)",
            ) from err
        sock.listen(4)
        sock.setblocking(False)
        return sock

    def _open_viewer(self) -> Window:
        try:
            return Window.launch(self.arm.env.model, self.arm.env.data, on_key=lambda key: None)
        except NoDisplayError:
            self.close()
            raise

    # -- the loop ----------------------------------------------------------------------------
    def serve_forever(self) -> None:
        log.info(
            "franka_sim: %s on %s (robot port %d, hand port %d), %s, scene %s, reality %s",
            self.arm.limits.name,
            self.host,
            self._robot_port,
            self._gripper_listener.getsockname()[1],
            "lockstep" if self.lockstep else "realtime 1 kHz",
            self.scene,
            self.arm.reality.name,
        )
        next_tick = time.perf_counter()
        try:
            while self._running:
                # Lockstep once the client answers. Before its first command libfranka reads
                # states beyond the one that showed its motion started (how many is the
                # client's affair), so they keep coming while the arm holds still: the first
                # few at 1 kHz, then slowly, so that a client stalled between two reads (a
                # loaded machine) sees one cycle pass, as its motion generator assumes, not a
                # jump of many.
                waiting = self.lockstep and self._sent_moving and not self._answering
                if self.lockstep and self._answering and self._sent_moving:
                    self._poll(0.0)
                    cmd = self._await_command()
                    next_tick = time.perf_counter()
                elif waiting and self._waiting_cycles >= FIRST_COMMAND_FAST_CYCLES:
                    cmd = self._await_first_command()
                    next_tick = time.perf_counter()
                else:
                    next_tick += DT
                    delay = next_tick - time.perf_counter()
                    if delay < -0.05:  # far behind (a stall): do not run to catch up
                        next_tick = time.perf_counter()
                    self._poll(max(delay, 0.0))
                    cmd = self._latest_command()
                    self._check_first_command()
                self._waiting_cycles += waiting
                if cmd is not None:
                    self._answering = True
                self._cycle(cmd)
        finally:
            self.close()

    def stop(self) -> None:
        self._running = False

    def _cycle(self, cmd: np.void | None) -> None:
        done = self.hand.step(DT)
        if done is not None:
            job, status = done
            self._gripper_reply(job.command, job.command_id, status)
        self.arm.step(cmd, count_lost=self._answering)
        if self.arm.event:
            self._answering = False
        if self.arm.event and self._motion_id is not None:
            status = (
                wire.MoveStatus.SUCCESS
                if self.arm.event == "finished"
                else wire.MoveStatus.REFLEX_ABORTED
            )
            if self.arm.event == "reflex":
                names = [
                    n for n, on in zip(wire.ERRORS, self.arm.last_motion_errors, strict=True) if on
                ]
                log.warning("franka_sim: reflex, the arm stopped: %s", ", ".join(names))
                if self.scene != "empty":
                    log.warning(
                        "franka_sim: for hardware in the loop (robot_ip=) serve --scene empty: "
                        "this scene's own objects push the arm where the client's scene has none"
                    )
            self._move_reply(self._motion_id, status)
            self._motion_id = None
            log.info(
                "franka_sim: motion %s after %d cycles, %d without a command",
                self.arm.event,
                self.arm.motion_cycles,
                self.arm.motion_missed,
            )
        self._publish_state()
        self._sent_moving = self.robot is not None and self.arm.moving
        gripper = self.gripper
        if gripper is not None and gripper.udp and self.message_id % GRIPPER_STATE_EVERY == 0:
            self._send_udp(self.hand.state(self.message_id), gripper.udp)
        viewer = self._viewer
        if viewer is not None and self.message_id % 16 == 0 and viewer.is_running():
            viewer.sync(full=False)  # also takes back the window's perturbation forces

    def _publish_state(self) -> None:
        """Send the arm's state under the next message id."""
        self.message_id += 1
        if self.robot is not None and self.robot.udp is not None:
            self.arm.write_state(self._state, self.message_id)
            self._send_udp(self._state.tobytes(), self.robot.udp)

    def _send_udp(self, data: bytes, address: tuple[str, int]) -> None:
        # a full buffer or a vanished client: the robot just sends the next one
        with contextlib.suppress(OSError):
            self._udp.sendto(data, address)

    # -- UDP commands ---------------------------------------------------------------------------
    def _read_commands(self) -> list[np.void]:
        out: list[np.void] = []
        size = self._state_protocol().command.itemsize
        while True:
            try:
                data, _ = self._udp.recvfrom(4096)
            except BlockingIOError:
                return out
            except OSError:
                return out
            if len(data) == size:
                out.append(np.frombuffer(data, dtype=self._state_protocol().command)[0])

    def _latest_command(self) -> np.void | None:
        """Paced: the command answering the last state, if it came in time (before the
        motion's first command, one answering any state of the motion)."""
        found = None
        for cmd in self._read_commands():
            answered = int(cmd["message_id"])
            if answered == self.message_id or (not self._answering and answered > 0):
                found = cmd
        return found

    def _check_first_command(self) -> None:
        """A motion whose client never sends its first command stops, as one that stops."""
        waited = time.perf_counter() - self._motion_started
        if self.arm.moving and not self._answering and waited > self.command_timeout:
            log.warning(
                "franka_sim: no first command %.1f s after the Move: the robot stops",
                self.command_timeout,
            )
            self.arm.reflex("communication_constraints_violation")

    def _await_first_command(self) -> np.void | None:
        """Lockstep, a motion's client not answering yet: its first command, or None once
        `FIRST_COMMAND_WAIT` has passed (the next state then goes out)."""
        deadline = time.perf_counter() + FIRST_COMMAND_WAIT
        while self.robot is not None and self.arm.moving and self._running:
            cmd = self._latest_command()
            if cmd is not None:
                return cmd
            remaining = deadline - time.perf_counter()
            if remaining <= 0.0:
                break
            self._poll(remaining, udp=True)
        self._check_first_command()
        return None

    def _await_command(self) -> np.void | None:
        """Lockstep: wait for the command answering the last state."""
        deadline = time.perf_counter() + self.command_timeout
        while self.robot is not None and self.arm.moving:
            for cmd in self._read_commands():
                if int(cmd["message_id"]) == self.message_id:
                    return cmd
            remaining = deadline - time.perf_counter()
            if remaining <= 0.0:
                log.warning(
                    "franka_sim: no command for %.1f s of wall time: the robot stops",
                    self.command_timeout,
                )
                self.arm.lost_in_a_row = LOST_CYCLES_LIMIT - 1
                return None
            self._poll(min(remaining, 0.05), udp=True)
        return None

    def _state_protocol(self) -> wire.Protocol:
        if self.robot is not None and self.robot.protocol is not None:
            return self.robot.protocol
        return wire.PROTOCOL_10

    # -- TCP ----------------------------------------------------------------------------------
    def _poll(self, timeout: float, udp: bool = False) -> None:
        socks = [self._gripper_listener]
        if self._robot_listener is not None:
            socks.append(self._robot_listener)
        socks += [p.sock for p in self._pending]
        socks += [p.sock for p in (self.robot, self.gripper) if p is not None]
        if udp:
            socks.append(self._udp)
        readable, _, _ = select.select(socks, [], [], timeout)
        for sock in readable:
            if sock is self._robot_listener or sock is self._gripper_listener:
                conn, address = sock.accept()
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                peer = _Peer(conn, address, is_gripper=sock is self._gripper_listener)
                self._pending.append(peer)
            elif sock is not self._udp:
                self._receive(sock)

    def _peer_of(self, sock: socket.socket) -> _Peer | None:
        for p in [*self._pending, self.robot, self.gripper]:
            if p is not None and p.sock is sock:
                return p
        return None

    def _receive(self, sock: socket.socket) -> None:
        peer = self._peer_of(sock)
        if peer is None:
            return
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            self._drop(peer, "closed the connection")
            return
        peer.buffer += data
        gripper = peer.is_gripper
        header = wire.GRIPPER_HEADER if gripper else wire.HEADER
        while len(peer.buffer) >= header.size:
            command, command_id, size = header.unpack_from(peer.buffer)
            if size < header.size:
                self._drop(peer, f"sent a malformed message (size {size})")
                return
            if len(peer.buffer) < size:
                return
            payload = bytes(peer.buffer[header.size : size])
            del peer.buffer[:size]
            if gripper:
                self._gripper_command(peer, command, command_id, payload)
            else:
                self._robot_command(peer, command, command_id, payload)
            if peer.sock.fileno() < 0:
                return

    def _drop(self, peer: _Peer, why: str) -> None:
        if peer is self.robot:
            if self.arm.moving:
                log.warning("franka_sim: the client %s mid-motion: the arm stops", why)
                self.arm.stop_motion()
            else:
                log.info("franka_sim: robot client %s:%d %s", *peer.address, why)
            self.robot = None
            self._motion_id = None
            try:  # the next client may come
                self._robot_listener = self._listen(self._robot_port)
            except AddressInUseError as err:
                log.error("franka_sim: no further clients: %s", err)
        elif peer is self.gripper:
            self.hand.abort()
            self.gripper = None
        if peer in self._pending:
            self._pending.remove(peer)
        peer.sock.close()

    def _reset(self, peer: _Peer) -> None:
        """Refuse a connection with a reset: Connect has no status for "busy", and libfranka
        waits on a connection merely closed; a reset it reports as an interrupted connection."""
        peer.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self._drop(peer, "refused")

    def _send(self, peer: _Peer, data: bytes) -> None:
        try:
            peer.sock.sendall(data)
        except OSError:
            self._drop(peer, "went away")

    # -- robot service --------------------------------------------------------------------------
    def _robot_command(self, peer: _Peer, command: int, command_id: int, payload: bytes) -> None:
        if peer.protocol is None:
            self._robot_connect(peer, command, command_id, payload)
            return
        protocol = peer.protocol
        name = protocol.command_of(command)
        if name is None:
            if protocol.version == 5 and command == wire.SET_FILTERS_V5:
                self._send(peer, wire.message(command, command_id, b"\x00"))
            elif protocol.version == 5 and command == wire.LOAD_MODEL_LIBRARY_V5:
                # the binary model library (libfcimodels), compiled here from the arm's URDF
                architecture, system = struct.unpack_from("<BB", payload.ljust(2, b"\xff"))
                try:
                    body = b"\x00" + model_library(self.arm.urdf, architecture, system)
                except ModelLibraryError as err:
                    log.error("franka_sim: no model library for the client: %s", err)
                    body = b"\x01"
                self._send(peer, wire.message(command, command_id, body))
            else:
                log.error("franka_sim: unknown command %d (protocol %d)", command, protocol.version)
                self._drop(peer, "sent an unknown command")
            return
        if name is wire.Command.MOVE:
            self._move(peer, command, command_id, payload)
        elif name is wire.Command.STOP_MOVE:
            if self._motion_id is not None:
                self._move_reply(self._motion_id, wire.MoveStatus.PREEMPTED)
                self._motion_id = None
            self.arm.stop_motion()
            self._publish_state()
            self._send(peer, wire.message(command, command_id, b"\x00"))
        elif name is wire.Command.GET_ROBOT_MODEL:
            body = b"\x00" + self.arm.urdf.encode()
            self._send(peer, wire.message(command, command_id, body))
        elif name is wire.Command.AUTOMATIC_ERROR_RECOVERY:
            status = 1 if self.arm.moving else 0
            if not status:
                self.arm.recover()
                # libfranka's read_once takes the newest state already received: one showing
                # the new mode must be there before the reply that ends the command.
                self._publish_state()
            self._send(peer, wire.message(command, command_id, bytes([status])))
        else:
            status = 1 if self.arm.moving else self._setting(name, payload)
            if status == 0:
                self._publish_state()  # the new frames and load, before the reply (as above)
            self._send(peer, wire.message(command, command_id, bytes([status])))

    def _setting(self, name: wire.Command, payload: bytes) -> int:
        """A setter's effect on the arm; its status (0 success, 2 invalid argument)."""
        values = np.frombuffer(payload, dtype="<f8", count=len(payload) // 8)
        arm = self.arm
        if not np.all(np.isfinite(values)):
            return 2
        if name is wire.Command.SET_COLLISION_BEHAVIOR:
            # lower/upper torque (acceleration), lower/upper torque (nominal), then forces
            arm.torque_lower = values[14:21].copy()
            arm.torque_upper = values[21:28].copy()
            arm.force_lower = values[40:46].copy()
            arm.force_upper = values[46:52].copy()
        elif name is wire.Command.SET_JOINT_IMPEDANCE:
            arm.impedance.stiffness = values[:7].copy()
        elif name is wire.Command.SET_CARTESIAN_IMPEDANCE:
            arm.K_x = values[:6].copy()
        elif name is wire.Command.SET_EE_TO_K:
            arm.EE_T_K = values[:16].reshape(4, 4, order="F").copy()
        elif name is wire.Command.SET_NE_TO_EE:
            arm.NE_T_EE = values[:16].reshape(4, 4, order="F").copy()
        elif name is wire.Command.SET_LOAD:
            arm.m_load = float(values[0])
            arm.F_x_Cload = values[1:4].copy()
            arm.I_load = values[4:13].copy()
        return 0

    def _robot_connect(self, peer: _Peer, command: int, command_id: int, payload: bytes) -> None:
        if command != 0 or len(payload) < 4:
            self._drop(peer, "did not start with Connect")
            return
        version, udp_port = struct.unpack_from("<HH", payload)
        protocol = wire.PROTOCOLS.get(version)
        if self.robot is not None:
            log.error(
                "franka_sim: refused a second client from %s:%d: %s:%d is connected (the robot "
                "serves one client; close the other first)",
                *peer.address,
                *self.robot.address,
            )
            self._reset(peer)
            return
        if protocol is None:
            log.error(
                "franka_sim: client %s:%d speaks robot protocol %d; this simulator speaks 10 (%s) "
                "and 5 (%s)",
                *peer.address,
                version,
                wire.PROTOCOL_10.libfranka,
                wire.PROTOCOL_5.libfranka,
            )
            reply = CONNECT_REPLY.pack(1, wire.PROTOCOL_10.version)
            self._send(peer, wire.message(command, command_id, reply))
            return
        peer.protocol = protocol
        peer.udp = (peer.address[0], udp_port)
        self._pending.remove(peer)
        self.robot = peer
        # The robot serves one client: while this one holds it, the port refuses others, so
        # libfranka's own error names the cause ("Connection to FCI refused"), where a
        # connection accepted and then dropped reads "TCP connection got interrupted".
        assert self._robot_listener is not None
        self._robot_listener.close()
        self._robot_listener = None
        self._state = np.zeros(1, dtype=protocol.state)
        log.info(
            "franka_sim: client %s:%d connected (robot protocol %d, %s)",
            *peer.address,
            version,
            protocol.libfranka,
        )
        self._send(peer, wire.message(command, command_id, CONNECT_REPLY.pack(0, version)))

    def _move(self, peer: _Peer, command: int, command_id: int, payload: bytes) -> None:
        protocol = peer.protocol
        assert protocol is not None
        fields = protocol.move_request.unpack_from(payload)
        controller_id, generator_id = fields[0], fields[1]
        try:
            controller = wire.ControllerMode(controller_id)
            generator = wire.MotionGenerator(generator_id + 1)
        except ValueError:
            self._send(
                peer,
                wire.message(
                    command,
                    command_id,
                    bytes([protocol.move_status(wire.MoveStatus.INVALID_ARGUMENT)]),
                ),
            )
            return
        refusal = self.arm.start_motion(controller, generator)
        if refusal:
            log.warning("franka_sim: Move refused: %s", refusal)
            status = wire.MoveStatus.COMMAND_NOT_POSSIBLE
        else:
            status = wire.MoveStatus.MOTION_STARTED
            log.info(
                "franka_sim: motion started: %s generator, %s controller",
                generator.name.lower(),
                controller.name.lower(),
            )
            self._motion_id = command_id
            self._answering = False
            self._waiting_cycles = 0
            self._motion_started = time.perf_counter()
        self._send(peer, wire.message(command, command_id, bytes([protocol.move_status(status)])))

    def _move_reply(self, motion_id: int, status: wire.MoveStatus) -> None:
        peer = self.robot
        if peer is None or peer.protocol is None:
            return
        wire_id = peer.protocol.command_id(wire.Command.MOVE)
        self._send(
            peer, wire.message(wire_id, motion_id, bytes([peer.protocol.move_status(status)]))
        )

    # -- gripper service ------------------------------------------------------------------------
    def _gripper_command(self, peer: _Peer, command: int, command_id: int, payload: bytes) -> None:
        if peer is not self.gripper:
            if command != wire.GRIPPER_CONNECT or len(payload) < 4:
                self._drop(peer, "did not start with Connect")
                return
            version, udp_port = struct.unpack_from("<HH", payload)
            if self.gripper is not None:
                log.error("franka_sim: refused a second hand client from %s:%d", *peer.address)
                self._reset(peer)
                return
            ok = version == wire.GRIPPER_VERSION
            if not ok:
                log.error(
                    "franka_sim: hand client speaks gripper protocol %d; this simulator speaks %d",
                    version,
                    wire.GRIPPER_VERSION,
                )
            else:
                peer.udp = (peer.address[0], udp_port)
                self._pending.remove(peer)
                self.gripper = peer
            reply = GRIPPER_CONNECT_REPLY.pack(0 if ok else 1, wire.GRIPPER_VERSION)
            self._send(peer, wire.gripper_message(command, command_id, reply))
            return
        if command != wire.GRIPPER_STOP and self.hand.job is not None:
            old = self.hand.abort()
            if old is not None:
                self._gripper_reply(old.command, old.command_id, wire.GRIPPER_ABORTED)
        if command == wire.GRIPPER_STOP:
            old = self.hand.abort()
            if old is not None:
                self._gripper_reply(old.command, old.command_id, wire.GRIPPER_ABORTED)
        status = self.hand.start(command, command_id, payload)
        if status is not None:
            self._gripper_reply(command, command_id, status)

    def _gripper_reply(self, command: int, command_id: int, status: int) -> None:
        if self.gripper is not None:
            body = struct.pack("<H", status)
            self._send(self.gripper, wire.gripper_message(command, command_id, body))

    def close(self) -> None:
        for peer in [*self._pending, self.robot, self.gripper]:
            if peer is not None:
                peer.sock.close()
        self._pending.clear()
        self.robot = self.gripper = None
        for sock in (self._robot_listener, self._gripper_listener, self._udp):
            if sock is not None:
                sock.close()
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        self.arm.env.close()
