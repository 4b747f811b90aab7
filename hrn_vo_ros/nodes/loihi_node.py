"""``loihi_node``: the resonator node preset to the spiking backend (phasor neurons, Loihi limits).

Same inputs, outputs and parameters as ``resonator_node`` (``backend.name`` is fixed to
``spiking``; tune ``backend.spiking.*``), plus:

* ``~/spike_raster`` (``sensor_msgs/Image`` mono8, at the map-image rate): the last oscillation
  cycle, one row per neuron (per factor: its input neurons, then its state neurons), one column
  per time step, brightness = spike payload;
* in ``/diagnostics``: per-iteration spikes, synaptic operations, neuron updates, and the
  estimated Loihi energy (µJ) and latency (µs) of an iteration (``core/spiking/accounting.py``).
"""

from __future__ import annotations

import sys
from typing import Any

from rclpy.parameter import Parameter
from sensor_msgs.msg import Image

from hrn_vo_ros.core.hrn.backends import SpikingDiagnostics
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.resonator_node import ResonatorNode

ACCOUNT_KEYS = ('spikes', 'synops', 'neuron_updates', 'neurons', 'cores', 'energy_uJ',
                'time_us', 'saturated')


class LoihiNode(ResonatorNode):
    """``resonator_node`` with ``backend.name = spiking``, a spike raster and accounting."""

    def __init__(self, **kwargs: Any) -> None:
        overrides = list(kwargs.pop('parameter_overrides', None) or [])
        overrides.append(Parameter('backend.name', value='spiking'))
        super().__init__('loihi_node', parameter_overrides=overrides, **kwargs)
        self._pub_raster = self.create_publisher(Image, '~/spike_raster', 2)
        sc = self._backend.config.spiking
        self.get_logger().info(f'spiking backend: {sc.precision}, T = {sc.steps_per_cycle} '
                               f'steps/cycle, {sc.weight_bits}-bit weights, {sc.synapse} synapses')

    def _publish_images(self, t_ns: int) -> bool:
        published = super()._publish_images(t_ns)
        if published and isinstance(self._hrn, SpikingDiagnostics):
            raster = self._hrn.raster().astype(float)
            frame = self._opts.config.camera_frame_id
            self._pub_raster.publish(ros_msgs.float_image_to_mono8(raster, t_ns, frame))
        return published

    def _extra_diagnostics(self) -> list[tuple[str, object]]:
        if not isinstance(self._hrn, SpikingDiagnostics):
            return []
        acc = self._hrn.account_summary()
        return [(f'loihi_{k}', f'{acc[k]:.4g}') for k in ACCOUNT_KEYS if k in acc]


def main(args: list[str] | None = None) -> int:
    """Console script ``loihi_node`` (``--ros-args`` are passed through)."""
    return run(LoihiNode, args)


if __name__ == '__main__':
    sys.exit(main())
