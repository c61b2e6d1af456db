"""Export a scenario for other FMI tools: an SSP 1.0 archive or an OSP system structure.

Both exports are written from the same resolved :class:`cosim.scenario.spec.Scenario` the
master runs: the instances (named as in the scenario, ``plant`` and ``controller``), their
FMUs, every explicit start value (with its unit), every connection, the stop time and the
communication step (with each instance's step multiple).

Every name they write is an identifier every importer accepts
(:data:`cosim.export.components.IDENTIFIER`, OMSimulator's rule, the strictest): the SSD's
model and system are named after the scenario id with every other character an underscore
(``bs-3`` -> ``bs_3``, :func:`cosim.export.components.model_name`), and the id itself is in
their ``description``; a scenario whose instance names break the rule is refused.

* ``export_ssp(scenario, "bs-3.ssp")`` (:mod:`cosim.export.ssp`) writes
  ``SystemStructure.ssd`` and the FMUs under ``resources/`` in one zip archive (SSP 1.0).
  The start values are an inline parameter set named :data:`PARAMETER_SET` on each
  component; ecos applies them only when that name is given
  (``EcosSimulation.init(parameter_set="initial")`` or ``ecos simulate --parameterSet
  initial``); libcosim and OMSimulator apply them as they load. The step is in annotations
  that libcosim (``com.opensimulationplatform``) and OMSimulator (``org.openmodelica``)
  read; ecos and fmpy.ssp take it as an argument.
* ``export_osp(scenario, "bs-3-osp")`` (:mod:`cosim.export.osp`) writes
  ``OspSystemStructure.xml`` beside copies of the FMUs (the format libcosim and the OSP
  tools load; it has no unit attribute, so each initial value carries its unit in a
  comment).

Of a scenario's events and faults, only gain and bias faults over the whole run are
exported, as linear transformations of their connections; anything else is refused
(:mod:`cosim.export.transformations`).

libcosim and ecos both step every instance at t from the outputs of t - h (Jacobi); the
master's Gauss-Seidel order has no counterpart in either file.

The modules: :mod:`~cosim.export.components` (what both formats need, from the scenario and
the FMUs' interfaces), :mod:`~cosim.export.ssp`, :mod:`~cosim.export.osp`,
:mod:`~cosim.export.files` (writing without leaving anything partial) and
:mod:`~cosim.export.command` (``auv-cosim export``).

Failures (an FMU without a variable the scenario uses, a path that cannot be written) raise
:class:`cosim.errors.CosimError` before anything is in place: the archive or folder is
built under a temporary name beside the target and renamed into place at the end.
"""

from cosim.export.osp import OSP_FILE, export_osp
from cosim.export.ssp import PARAMETER_SET, export_ssp

__all__ = ["OSP_FILE", "PARAMETER_SET", "export_osp", "export_ssp"]
