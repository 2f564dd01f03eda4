"""An NI gRPC Device Server for the emulated NI-DAQmx devices (`nidaq_device.py`), on
the service NI generated for it: `nidaqmx._stubs.nidaqmx_pb2_grpc.NiDAQmxServicer`,
which `nidaqmx[grpc]` ships. NI's own client library (`nidaqmx.Task(grpc_options=...)`)
drives it as it drives a PXI controller's or a cRIO's device server.

Served as NI's server (ni/grpc-device) does: a task is a session named by the
client's `session_name`; a DAQmx error is the call's gRPC status UNKNOWN with DAQmx's
words as its details and the code in the trailing metadata `ni-error` (a read's also
says how many samples it read, `ni-samps-per-chan-read`), which nidaqmx raises as its
`DaqError` with that code. The calls served are those a program of channels, sample
clock, reads and writes makes (the `nidaqmx` driver's and nidaqmx's own around them:
its version query, attribute reads of the task and device, error strings); any other
answers UNIMPLEMENTED, as a server without that function would.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent import futures

import grpc
from nidaqmx._stubs import nidaqmx_pb2 as pb
from nidaqmx._stubs import nidaqmx_pb2_grpc as pbg

from pamd.emulate.nidaq_device import Card, DaqmxError, EmuChannel, EmulatedDaq, EmuTask

#: the NI-DAQmx version the server reports (major, minor, update)
VERSION = {0x1272: 25, 0x1923: 3, 0x2F22: 0}
HWTSP = 12522  # DAQmx_Val_HWTimedSinglePoint
DEFAULT_TERMINAL = -1
#: the counter input terminals (A, B, Z) as channel attributes
ROUTES = (0x219D, 0x219E, 0x219F)
TASK_NAME, NUM_CHANS_READ, NUM_CHANS_WRITE = 0x1276, 0x217B, 0x217E
TOTAL_ACQUIRED, PRODUCT_TYPE = 0x192A, 0x0631
TASK_START, TASK_STOP = 0, 1
#: worker threads: each wait for a sample clock holds one
WORKERS = 16


def _raw(request: object, name: str) -> int:
    """An enum field as nidaqmx sends it (`<name>_raw`), or its enum member."""
    which = request.WhichOneof(f"{name}_enum")  # type: ignore[attr-defined]
    if which is None:
        raw = f"{name}_raw"
        return int(getattr(request, raw) if hasattr(request, raw) else getattr(request, name))
    return int(getattr(request, which))


class NiDaqmxService(pbg.NiDAQmxServicer):  # type: ignore[misc]  # NI's generated, untyped
    """The NiDAQmx service over the emulated devices, by device name."""

    def __init__(self, devices: dict[str, EmulatedDaq]) -> None:
        self.devices = {name.lower(): d for name, d in devices.items()}
        self.tasks: dict[str, EmuTask] = {}
        self._lock = threading.Lock()
        self.calls = 0
        self.counts: dict[str, int] = {}  # calls by function (its reply's name)

    # -- plumbing ---------------------------------------------------------------------------------
    def _task(self, session: object) -> EmuTask:
        name = str(session.name)  # type: ignore[attr-defined]
        with self._lock:
            task = self.tasks.get(name)
        if task is None:
            raise DaqmxError(-200088, f"Task specified is invalid or does not exist.\n"
                             f"Task Name: {name}")
        return task

    def _device(self, physical: str) -> EmulatedDaq:
        dev = physical.lstrip("/").split("/", 1)[0].lower()
        found = self.devices.get(dev)
        if found is None:
            names = ", ".join(d.name for d in self.devices.values())
            raise DaqmxError(-200220, f"Device identifier is invalid.\nDevice Specified: "
                             f"{dev}\nSuggested Device(s): {names}")
        return found

    def _call(self, context: grpc.ServicerContext, reply: type, work: Callable[[], object],
              read: bool = False) -> object:
        """Run `work`; a DaqmxError becomes NI's error status (module docstring)."""
        self.calls += 1
        name = reply.__name__.removesuffix("Response")
        self.counts[name] = self.counts.get(name, 0) + 1
        try:
            out = work()
        except DaqmxError as exc:
            metadata = [("ni-error", str(exc.code))]
            if read:
                metadata.append(("ni-samps-per-chan-read", "0"))
            context.set_trailing_metadata(tuple(metadata))
            context.set_code(grpc.StatusCode.UNKNOWN)
            context.set_details(exc.text)
            return reply()
        return out if out is not None else reply()

    def _add(self, session: object, physical: str, make: Callable[[Card], EmuChannel]) -> None:
        task = self._task(session)
        device = self._device(physical)
        if task.device is not device:
            if task.channels:
                raise DaqmxError(-200559, "Channels of one task are on one device here.")
            task.device.clear(task)
            with device.lock:
                device.tasks[task.name] = task
            task.device, task.epoch = device, device.epoch
        device.add(task, make)

    # -- tasks -------------------------------------------------------------------------------------
    def CreateTask(self, request: pb.CreateTaskRequest, context: grpc.ServicerContext
                   ) -> object:
        def work() -> object:
            name = request.session_name or f"_unnamedTask<{len(self.tasks)}>"
            device = next(iter(self.devices.values()))
            task = device.create_task(name)
            with self._lock:
                self.tasks[name] = task
            reply = pb.CreateTaskResponse(new_session_initialized=True)
            reply.task.name = name
            return reply
        return self._call(context, pb.CreateTaskResponse, work)

    def ClearTask(self, request: pb.ClearTaskRequest, context: grpc.ServicerContext) -> object:
        def work() -> None:
            name = request.task.name
            with self._lock:
                task = self.tasks.pop(name, None)
            if task is not None:
                task.device.clear(task)
        return self._call(context, pb.ClearTaskResponse, work)

    def StartTask(self, request: pb.StartTaskRequest, context: grpc.ServicerContext) -> object:
        def work() -> None:
            task = self._task(request.task)
            task.device.start(task)
        return self._call(context, pb.StartTaskResponse, work)

    def StopTask(self, request: pb.StopTaskRequest, context: grpc.ServicerContext) -> object:
        def work() -> None:
            task = self._task(request.task)
            task.device.stop(task)
        return self._call(context, pb.StopTaskResponse, work)

    def TaskControl(self, request: pb.TaskControlRequest, context: grpc.ServicerContext
                    ) -> object:
        def work() -> None:
            task = self._task(request.task)
            action = _raw(request, "action")
            if action == TASK_START:
                task.device.start(task)
            elif action in (TASK_STOP, 6):
                task.device.stop(task)
        return self._call(context, pb.TaskControlResponse, work)

    # -- channels ----------------------------------------------------------------------------------
    def CreateAIVoltageChan(self, request: pb.CreateAIVoltageChanRequest,
                            context: grpc.ServicerContext) -> object:
        def work() -> None:
            r = request
            self._add(r.task, r.physical_channel, lambda card: card.ai_voltage(
                r.physical_channel, r.name_to_assign_to_channel or r.physical_channel,
                _raw(r, "terminal_config"), r.min_val, r.max_val))
        return self._call(context, pb.CreateAIVoltageChanResponse, work)

    def CreateAIForceBridgeTwoPointLinChan(
            self, request: pb.CreateAIForceBridgeTwoPointLinChanRequest,
            context: grpc.ServicerContext) -> object:
        def work() -> None:
            r = request
            self._add(r.task, r.physical_channel, lambda card: card.bridge(
                r.physical_channel, r.name_to_assign_to_channel or r.physical_channel,
                r.min_val, r.max_val, r.voltage_excit_val,
                r.second_electrical_val - r.first_electrical_val,
                r.second_physical_val - r.first_physical_val))
        return self._call(context, pb.CreateAIForceBridgeTwoPointLinChanResponse, work)

    def CreateCILinEncoderChan(self, request: pb.CreateCILinEncoderChanRequest,
                               context: grpc.ServicerContext) -> object:
        def work() -> None:
            r = request
            per_edge = {10090: 1, 10091: 2, 10092: 4, 10313: 1}.get(_raw(r, "decoding_type"), 4)
            self._add(r.task, r.counter, lambda card: card.encoder(
                r.counter, r.name_to_assign_to_channel or r.counter,
                r.dist_per_pulse / per_edge, r.initial_pos,
                r.zidx_val if r.zidx_enable else None))
        return self._call(context, pb.CreateCILinEncoderChanResponse, work)

    def CreateAOVoltageChan(self, request: pb.CreateAOVoltageChanRequest,
                            context: grpc.ServicerContext) -> object:
        def work() -> None:
            r = request
            self._add(r.task, r.physical_channel, lambda card: card.ao(
                r.physical_channel, r.name_to_assign_to_channel or r.physical_channel,
                r.min_val, r.max_val))
        return self._call(context, pb.CreateAOVoltageChanResponse, work)

    def CreateDIChan(self, request: pb.CreateDIChanRequest, context: grpc.ServicerContext
                     ) -> object:
        def work() -> None:
            r = request
            self._add(r.task, r.lines, lambda card: card.lines(
                r.lines, r.name_to_assign_to_lines or r.lines, "di"))
        return self._call(context, pb.CreateDIChanResponse, work)

    def CreateDOChan(self, request: pb.CreateDOChanRequest, context: grpc.ServicerContext
                     ) -> object:
        def work() -> None:
            r = request
            self._add(r.task, r.lines, lambda card: card.lines(
                r.lines, r.name_to_assign_to_lines or r.lines, "do"))
        return self._call(context, pb.CreateDOChanResponse, work)

    def SetChanAttributeString(self, request: pb.SetChanAttributeStringRequest,
                               context: grpc.ServicerContext) -> object:
        def work() -> None:
            task = self._task(request.task)
            if _raw(request, "attribute") not in ROUTES:
                raise DaqmxError(-200452, "Specified property is not supported by the device "
                                 "or is not applicable to the task.")
            task.device.check(task, lambda card: card.route(request.value))
        return self._call(context, pb.SetChanAttributeStringResponse, work)

    def CfgSampClkTiming(self, request: pb.CfgSampClkTimingRequest,
                         context: grpc.ServicerContext) -> object:
        def work() -> None:
            task = self._task(request.task)
            task.device.timing(task, request.rate, request.source,
                               _raw(request, "sample_mode") == HWTSP)
        return self._call(context, pb.CfgSampClkTimingResponse, work)

    # -- the sample clock, reads and writes ------------------------------------------------------
    def WaitForNextSampleClock(self, request: pb.WaitForNextSampleClockRequest,
                               context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            late = task.device.wait_next_sample_clock(task, request.timeout)
            return pb.WaitForNextSampleClockResponse(is_late=late)
        return self._call(context, pb.WaitForNextSampleClockResponse, work)

    def ReadAnalogF64(self, request: pb.ReadAnalogF64Request, context: grpc.ServicerContext
                      ) -> object:
        def work() -> object:
            task = self._task(request.task)
            values = task.device.read(task)
            reply = pb.ReadAnalogF64Response(samps_per_chan_read=1)
            reply.read_array.extend(values[:request.array_size_in_samps])
            return reply
        return self._call(context, pb.ReadAnalogF64Response, work, read=True)

    def ReadCounterScalarF64(self, request: pb.ReadCounterScalarF64Request,
                             context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            return pb.ReadCounterScalarF64Response(value=task.device.read(task)[0])
        return self._call(context, pb.ReadCounterScalarF64Response, work)

    def ReadDigitalLines(self, request: pb.ReadDigitalLinesRequest,
                         context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            bits = bytes(1 if v else 0 for v in task.device.read(task))
            return pb.ReadDigitalLinesResponse(read_array=bits[:request.array_size_in_bytes],
                                               samps_per_chan_read=1, num_bytes_per_samp=1)
        return self._call(context, pb.ReadDigitalLinesResponse, work, read=True)

    def WriteAnalogF64(self, request: pb.WriteAnalogF64Request,
                       context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            task.device.write(task, list(request.write_array))
            return pb.WriteAnalogF64Response(samps_per_chan_written=1)
        return self._call(context, pb.WriteAnalogF64Response, work)

    def WriteDigitalLines(self, request: pb.WriteDigitalLinesRequest,
                          context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            task.device.write(task, [float(b) for b in request.write_array])
            return pb.WriteDigitalLinesResponse(samps_per_chan_written=1)
        return self._call(context, pb.WriteDigitalLinesResponse, work)

    # -- attributes and errors --------------------------------------------------------------------
    def GetSystemInfoAttributeUInt32(self, request: pb.GetSystemInfoAttributeUInt32Request,
                                     context: grpc.ServicerContext) -> object:
        return pb.GetSystemInfoAttributeUInt32Response(
            value=VERSION.get(_raw(request, "attribute"), 0))

    def GetTaskAttributeString(self, request: pb.GetTaskAttributeStringRequest,
                               context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            return pb.GetTaskAttributeStringResponse(value=task.name)
        return self._call(context, pb.GetTaskAttributeStringResponse, work)

    def GetReadAttributeUInt32(self, request: pb.GetReadAttributeUInt32Request,
                               context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            return pb.GetReadAttributeUInt32Response(value=len(task.channels))
        return self._call(context, pb.GetReadAttributeUInt32Response, work)

    def GetWriteAttributeUInt32(self, request: pb.GetWriteAttributeUInt32Request,
                                context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            return pb.GetWriteAttributeUInt32Response(value=len(task.channels))
        return self._call(context, pb.GetWriteAttributeUInt32Response, work)

    def GetReadAttributeUInt64(self, request: pb.GetReadAttributeUInt64Request,
                               context: grpc.ServicerContext) -> object:
        def work() -> object:
            task = self._task(request.task)
            if _raw(request, "attribute") != TOTAL_ACQUIRED:
                raise DaqmxError(-200452, "Specified property is not supported.")
            return pb.GetReadAttributeUInt64Response(value=task.device.acquired(task))
        return self._call(context, pb.GetReadAttributeUInt64Response, work)

    def GetDeviceAttributeString(self, request: pb.GetDeviceAttributeStringRequest,
                                 context: grpc.ServicerContext) -> object:
        def work() -> object:
            device = self._device(request.device_name)
            if _raw(request, "attribute") != PRODUCT_TYPE:
                raise DaqmxError(-200452, "Specified property is not supported.")
            return pb.GetDeviceAttributeStringResponse(value=device.product.name)
        return self._call(context, pb.GetDeviceAttributeStringResponse, work)

    def GetErrorString(self, request: pb.GetErrorStringRequest, context: grpc.ServicerContext
                       ) -> object:
        return pb.GetErrorStringResponse(error_string=f"DAQmx error {request.error_code}")


class DaqServer:
    """A gRPC server of `NiDaqmxService` on a loopback port, in this process."""

    def __init__(self, devices: dict[str, EmulatedDaq], host: str, port: int) -> None:
        self.service = NiDaqmxService(devices)
        self.server = grpc.server(futures.ThreadPoolExecutor(max_workers=WORKERS,
                                                             thread_name_prefix="emu-nidaq"))
        pbg.add_NiDAQmxServicer_to_server(self.service, self.server)
        bound = self.server.add_insecure_port(f"{host}:{port}")
        if bound == 0:
            raise OSError(f"cannot serve NI-DAQmx's gRPC interface on {host}:{port} (taken?)")
        self.address = f"{host}:{bound}"

    def start(self) -> None:
        self.server.start()

    def stop(self) -> None:
        self.server.stop(grace=0.5).wait(5.0)
