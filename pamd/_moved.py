"""The module names pamd had before issue 41's move, each to the module that holds its
code now: a script that imports an old name (`from pamd.view.recording import
Recording`, `python -m pamd.view.layout`) keeps working, told where the code is now
(a `FutureWarning`; the old names go in a later release).

`pamd/__init__.py` puts a finder last on `sys.meta_path` that asks `OldNames` here, so
it is asked only for a name nothing else found: an import under a present name never
reaches it and never loads this module (the io process does not). An old module name
is the new module itself (one module object, so classes stay the same); an old
package name is a package of its own whose attributes are the new package's and whose
submodules come from this table. `pamd.loop` and `pamd.daemon` name packages now (the
loop process's, the main process's): `pamd.loop.loop` and `pamd.daemon.daemon` are
the old modules. This table is generated with the move
(/work/wt/n41-move/move.py); edit it there.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import warnings
from collections.abc import Sequence
from types import CodeType, ModuleType

#: old name -> new name, every module and package the move renamed
MOVED: dict[str, str] = {
    "pamd.atomic": "pamd.wire.atomic",
    "pamd.calibration": "pamd.loop.devices.datum_file",
    "pamd.cli": "pamd.client.cli",
    "pamd.cli.check_config": "pamd.client.cli.check_config",
    "pamd.cli.collect": "pamd.client.cli.collect",
    "pamd.cli.commission": "pamd.client.cli.commission",
    "pamd.cli.commission_map": "pamd.client.cli.commission_map",
    "pamd.cli.emulate": "pamd.client.cli.emulate",
    "pamd.cli.evaluate": "pamd.client.cli.evaluate",
    "pamd.cli.exit_codes": "pamd.client.cli.exit_codes",
    "pamd.cli.home": "pamd.client.cli.home",
    "pamd.cli.main": "pamd.client.cli.main",
    "pamd.cli.model": "pamd.client.cli.model",
    "pamd.cli.net": "pamd.client.cli.net",
    "pamd.cli.numbers": "pamd.client.cli.numbers",
    "pamd.cli.offline": "pamd.client.cli.offline",
    "pamd.cli.progress": "pamd.client.cli.progress",
    "pamd.cli.recordings": "pamd.client.cli.recordings",
    "pamd.cli.reference": "pamd.client.cli.reference",
    "pamd.cli.router": "pamd.client.cli.router",
    "pamd.cli.run": "pamd.client.cli.run",
    "pamd.cli.run_start": "pamd.client.cli.run_start",
    "pamd.cli.service": "pamd.client.cli.service",
    "pamd.cli.tare": "pamd.client.cli.tare",
    "pamd.cli.train": "pamd.client.cli.train",
    "pamd.cli.tune": "pamd.client.cli.tune",
    "pamd.cli.view": "pamd.client.cli.view",
    "pamd.commands": "pamd.loop.commands",
    "pamd.commands.adapt": "pamd.loop.commands.adapt_verbs",
    "pamd.commands.apply": "pamd.loop.commands.apply",
    "pamd.commands.guards": "pamd.loop.commands.guards",
    "pamd.commands.model_file": "pamd.loop.commands.model_file",
    "pamd.commands.motion": "pamd.loop.commands.motion_verbs",
    "pamd.commands.named_files": "pamd.loop.commands.named_files",
    "pamd.commands.offload": "pamd.loop.commands.offload",
    "pamd.commands.parse": "pamd.loop.commands.parse",
    "pamd.commands.pending": "pamd.loop.commands.pending",
    "pamd.commands.plan": "pamd.loop.commands.plan_verbs",
    "pamd.commands.plan_file": "pamd.loop.commands.plan_file",
    "pamd.commands.registry": "pamd.loop.commands.verb_registry",
    "pamd.commands.rig": "pamd.loop.commands.rig_verbs",
    "pamd.commands.schema": "pamd.loop.commands.prepared",
    "pamd.commands.tune": "pamd.loop.commands.tune_verbs",
    "pamd.commands.verbs": "pamd.loop.commands.verbs",
    "pamd.commission": "pamd.client.commission",
    "pamd.commission.checks": "pamd.client.commission.sign_checks",
    "pamd.commission.mapfit": "pamd.client.commission.mapfit",
    "pamd.commission.mapreport": "pamd.client.commission.mapreport",
    "pamd.commission.maprun": "pamd.client.commission.maprun",
    "pamd.commission.mapsweep": "pamd.client.commission.mapsweep",
    "pamd.commission.measure": "pamd.client.commission.measure",
    "pamd.commission.moves": "pamd.client.commission.moves",
    "pamd.commission.probe": "pamd.client.commission.probe",
    "pamd.commission.propose": "pamd.client.commission.propose",
    "pamd.commission.report": "pamd.client.commission.commission_report",
    "pamd.commission.run": "pamd.client.commission.commissioning",
    "pamd.config.actuation": "pamd.config.actuation_rules",
    "pamd.config.chain": "pamd.config.chain_rules",
    "pamd.config.plausibility": "pamd.config.plausibility_rules",
    "pamd.config.timing": "pamd.config.timing_rules",
    "pamd.control": "pamd.loop.control",
    "pamd.control.actuation": "pamd.loop.control.actuation",
    "pamd.control.adapt": "pamd.loop.control.adapt",
    "pamd.control.feedforward": "pamd.loop.control.feedforward",
    "pamd.control.ilc": "pamd.loop.control.ilc",
    "pamd.control.incremental_pid": "pamd.loop.control.incremental_pid",
    "pamd.control.inputs": "pamd.loop.control.inputs",
    "pamd.control.length_control": "pamd.loop.control.length_control",
    "pamd.control.length_targets": "pamd.loop.control.length_targets",
    "pamd.control.model_check": "pamd.loop.control.model_check",
    "pamd.control.muscle": "pamd.loop.control.muscle",
    "pamd.control.off_data": "pamd.loop.control.off_data",
    "pamd.control.onoff": "pamd.loop.control.onoff",
    "pamd.control.pid": "pamd.loop.control.pid",
    "pamd.control.pressure_loop": "pamd.loop.control.pressure_loop",
    "pamd.control.relay": "pamd.loop.control.relay",
    "pamd.control.rig_chain": "pamd.loop.control.rig_chain",
    "pamd.control.rig_deadman": "pamd.loop.control.rig_deadman",
    "pamd.control.rig_report": "pamd.loop.control.rig_report",
    "pamd.control.rig_safe_state": "pamd.loop.control.rig_safe_state",
    "pamd.control.rig_startup": "pamd.loop.control.rig_startup",
    "pamd.control.setpoint": "pamd.loop.control.setpoint",
    "pamd.control.settings": "pamd.loop.control.settings",
    "pamd.control.tuning": "pamd.loop.control.tuning",
    "pamd.control.valve_pulse": "pamd.loop.control.valve_pulse",
    "pamd.controller": "pamd.loop.control.controller",
    "pamd.declare": "pamd.wire.declare",
    "pamd.declare.docs": "pamd.wire.declare.fields_doc",
    "pamd.declare.events": "pamd.wire.declare.events",
    "pamd.declare.fields": "pamd.wire.declare.fields",
    "pamd.declare.jsonsafe": "pamd.wire.declare.jsonsafe",
    "pamd.declare.summary": "pamd.wire.declare.summary_keys",
    "pamd.errors": "pamd.wire.errors",
    "pamd.experiment": "pamd.loop.experiment",
    "pamd.experiment.manifest": "pamd.loop.experiment.manifest",
    "pamd.experiment.plan": "pamd.loop.experiment.plan",
    "pamd.experiment.sequencer": "pamd.loop.experiment.sequencer",
    "pamd.experiment.stepfiles": "pamd.loop.experiment.stepfiles",
    "pamd.experiment.timeline": "pamd.loop.experiment.timeline",
    "pamd.harness": "pamd.loop.harness",
    "pamd.io.link": "pamd.loop.io_link",
    "pamd.io.process": "pamd.iohost.process",
    "pamd.io.session": "pamd.daemon.io_session",
    "pamd.io.spec": "pamd.iohost.io_spec",
    "pamd.ipc.ring": "pamd.wire.ring",
    "pamd.metrics": "pamd.models.metrics",
    "pamd.models.anfis.checks": "pamd.models.data.checks",
    "pamd.models.anfis.extraction": "pamd.models.data.extraction",
    "pamd.models.anfis.plots": "pamd.models.anfis.anfis_plots",
    "pamd.models.anfis.recordings": "pamd.models.data.recordings",
    "pamd.models.anfis.samples": "pamd.models.data.samples",
    "pamd.models.anfis.splitting": "pamd.models.data.splitting",
    "pamd.models.anfis.training": "pamd.models.anfis.hybrid",
    "pamd.net.board": "pamd.wire.board",
    "pamd.net.cleartext": "pamd.wire.cleartext",
    "pamd.net.client.client": "pamd.client.remote",
    "pamd.net.credential": "pamd.wire.credential",
    "pamd.net.host": "pamd.daemon.host",
    "pamd.net.host.collections": "pamd.daemon.host.collections",
    "pamd.net.host.host": "pamd.daemon.host.host",
    "pamd.net.host.ports": "pamd.daemon.host.parts",
    "pamd.net.host.resolve": "pamd.daemon.host.resolve",
    "pamd.net.host.status": "pamd.daemon.host.snapshot",
    "pamd.net.keys": "pamd.wire.keys",
    "pamd.net.local": "pamd.wire.local_channel",
    "pamd.net.node.answer": "pamd.iohost.answer",
    "pamd.net.node.intake": "pamd.iohost.intake",
    "pamd.net.node.node": "pamd.iohost.node",
    "pamd.net.ratelimit": "pamd.iohost.ratelimit",
    "pamd.net.seams": "pamd.wire.seams",
    "pamd.net.spec": "pamd.wire.net_spec",
    "pamd.net.status": "pamd.wire.status",
    "pamd.net.telemetry": "pamd.wire.telemetry",
    "pamd.net.zconf": "pamd.wire.zconf",
    "pamd.plugins": "pamd.config.plugins",
    "pamd.profile_kinds": "pamd.wire.shape_names",
    "pamd.record": "pamd.wire.record",
    "pamd.record.cdr": "pamd.wire.record.cdr",
    "pamd.record.control": "pamd.wire.record.control",
    "pamd.record.files": "pamd.wire.record.files",
    "pamd.record.mcapw": "pamd.wire.record.mcapw",
    "pamd.record.meta": "pamd.daemon.record_meta",
    "pamd.record.recorder": "pamd.iohost.recorder",
    "pamd.record.spec": "pamd.wire.record.record_spec",
    "pamd.record.tables": "pamd.wire.record.tables",
    "pamd.rig": "pamd.loop.devices.bindings",
    "pamd.rt": "pamd.loop.rt",
    "pamd.safety": "pamd.loop.safety",
    "pamd.safety.chain": "pamd.loop.safety.chain",
    "pamd.safety.datums": "pamd.loop.safety.datums",
    "pamd.safety.envelope": "pamd.loop.safety.envelope",
    "pamd.safety.length_rate": "pamd.loop.safety.length_rate",
    "pamd.safety.limiter": "pamd.loop.safety.limiter",
    "pamd.safety.limits": "pamd.loop.safety.limits",
    "pamd.safety.load_check": "pamd.loop.safety.load_check",
    "pamd.safety.plausibility": "pamd.loop.safety.plausibility",
    "pamd.safety.supervisor": "pamd.loop.safety.supervisor",
    "pamd.schema": "pamd.wire.schema",
    "pamd.schema.domains": "pamd.wire.schema.domains",
    "pamd.schema.engine": "pamd.wire.schema.engine",
    "pamd.schema.yamlload": "pamd.wire.schema.yamlload",
    "pamd.service": "pamd.daemon.service",
    "pamd.service.install": "pamd.daemon.service.install",
    "pamd.service.keeper": "pamd.daemon.service.keeper",
    "pamd.service.notify": "pamd.daemon.service.notify",
    "pamd.service.persistence": "pamd.daemon.service.persistence",
    "pamd.service.ports": "pamd.daemon.service.ports",
    "pamd.service.reload": "pamd.daemon.service.reload",
    "pamd.service.reloader": "pamd.daemon.service.reloader",
    "pamd.service.restart": "pamd.daemon.service.restart",
    "pamd.service.riglock": "pamd.daemon.service.riglock",
    "pamd.service.safe_outputs": "pamd.daemon.service.safe_outputs",
    "pamd.service.state": "pamd.daemon.service.state",
    "pamd.service.watchdog": "pamd.daemon.service.watchdog",
    "pamd.sim.onoff": "pamd.sim.solenoid",
    "pamd.stalls": "pamd.loop.stalls",
    "pamd.summary": "pamd.loop.control.summary",
    "pamd.tick": "pamd.wire.tick",
    "pamd.timing": "pamd.loop.tick_timing",
    "pamd.tune": "pamd.client.tune",
    "pamd.tune.onoff": "pamd.client.tune.onoff_steps",
    "pamd.tune.onoff_plot": "pamd.client.tune.onoff_plot",
    "pamd.tune.onoff_run": "pamd.client.tune.onoff_run",
    "pamd.tune.placement": "pamd.client.tune.placement",
    "pamd.tune.relay": "pamd.client.tune.relay_run",
    "pamd.tune.report": "pamd.client.tune.tune_report",
    "pamd.tune.run": "pamd.client.tune.ident_run",
    "pamd.tune.save": "pamd.client.tune.save",
    "pamd.tune.steps": "pamd.client.tune.step_responses",
    "pamd.tune.yamledit": "pamd.client.tune.yamledit",
    "pamd.verbs": "pamd.wire.verbs",
    "pamd.verbs.schema": "pamd.wire.verbs.args",
    "pamd.verbs.table": "pamd.wire.verbs.table",
    "pamd.version": "pamd.wire.version",
    "pamd.view.client": "pamd.client.connect",
    "pamd.view.collection": "pamd.client.collection",
    "pamd.view.csvtext": "pamd.client.csvtext",
    "pamd.view.export": "pamd.client.export",
    "pamd.view.fields": "pamd.client.field_info",
    "pamd.view.judging": "pamd.client.judging",
    "pamd.view.layout": "pamd.client.layout",
    "pamd.view.live": "pamd.iohost.live",
    "pamd.view.matscan": "pamd.client.matscan",
    "pamd.view.plots": "pamd.client.plots",
    "pamd.view.recording": "pamd.client.recording",
    "pamd.view.spec": "pamd.iohost.viewer_spec",
    "pamd.view.table_checks": "pamd.client.table_checks",
    "pamd.view.tables": "pamd.client.training_tables",
}

#: the packages the move removed (their modules went to several places): an import
#: of one gets an empty package, through which its old submodules are found
REMOVED: frozenset[str] = frozenset({
    "pamd.io",
    "pamd.ipc",
    "pamd.net",
    "pamd.net.client",
    "pamd.net.node",
    "pamd.view",
})


def _told(old: str, new: str) -> None:
    warnings.warn(f"{old} is now {new}: import that (the old name goes in a later "
                  "release; CHANGELOG.md)", FutureWarning, stacklevel=4)


class _Alias(importlib.abc.Loader):
    """Loads an old name as the module that holds its code now."""

    def __init__(self, old: str, new: str) -> None:
        self.old, self.new = old, new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        if self.new:  # a removed package is no module of its own to be told about
            _told(self.old, self.new)
        if spec.submodule_search_locations is None:
            return importlib.import_module(self.new)
        # a package: its own module object (its submodules are found by old name,
        # here), with the new package's attributes
        package = ModuleType(self.old)
        package.__dict__["__path__"] = []
        if self.new:
            target = importlib.import_module(self.new)

            def attribute(name: str) -> object:
                return getattr(target, name)
            package.__dict__["__getattr__"] = attribute
        return package

    def exec_module(self, module: ModuleType) -> None:
        return None

    def get_code(self, fullname: str) -> CodeType | None:
        """`python -m` of an old name runs the new module's code."""
        spec = importlib.util.find_spec(self.new)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "get_code"):
            return None
        _told(self.old, self.new)
        code: CodeType | None = spec.loader.get_code(self.new)
        return code


class OldNames(importlib.abc.MetaPathFinder):
    """The finder of the old names (last on `sys.meta_path`)."""

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname in REMOVED:
            return importlib.machinery.ModuleSpec(fullname, _Alias(fullname, ""),
                                                  is_package=True)
        new = MOVED.get(fullname)
        if new is None:
            return None
        found = importlib.util.find_spec(new)
        is_package = found is not None and found.submodule_search_locations is not None
        # its file's path, so that `python -m` of the old name has the new one's __file__
        return importlib.machinery.ModuleSpec(fullname, _Alias(fullname, new),
                                              origin=found.origin if found else None,
                                              is_package=is_package)

