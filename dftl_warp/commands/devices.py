"""``dftl-warp devices``: list the Warp devices this machine offers."""

from __future__ import annotations


def add_parser(sub):
    p = sub.add_parser("devices", help="list the devices dftl-warp can simulate on",
                       description="List the Warp devices (cpu, cuda:N) available on this machine.")
    p.set_defaults(run=run)


def run(args) -> int:
    import warp as wp

    from ..core.devices import default_device, init_warp

    init_warp()
    default = default_device()   # a bad $DFTL_WARP_DEVICE: its one line (naming these devices), before any output
    for name in wp.get_devices():
        device = wp.get_device(name)
        print(f"{device.alias:10s} {device.name}")
    print(f"default: {default}")
    return 0
