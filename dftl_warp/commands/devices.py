"""``dftl-warp devices``: list the Warp devices this machine offers."""

from __future__ import annotations


def add_parser(sub):
    p = sub.add_parser("devices", help="list the devices dftl-warp can simulate on",
                       description="List the Warp devices (cpu, cuda:N) available on this machine.")
    p.set_defaults(run=run)


def run(args) -> int:
    import warp as wp

    wp.init()
    for name in wp.get_devices():
        device = wp.get_device(name)
        print(f"{device.alias:10s} {device.name}")
    return 0
