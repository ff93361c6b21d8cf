"""``dftl-warp devices``: the devices Warp offers here, and the default the other commands use."""

from dftl_warp.cli import main


def test_devices_lists_cpu_and_the_default(monkeypatch, capsys):
    monkeypatch.setenv("DFTL_WARP_DEVICE", "cpu")
    assert main(["devices"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[0] == "cpu" and out[-1] == "default: cpu"


def test_a_bad_device_variable_is_one_line_and_no_half_list(monkeypatch, capsys):
    monkeypatch.setenv("DFTL_WARP_DEVICE", "bogus")
    assert main(["devices"]) == 2
    out, err = capsys.readouterr()
    assert out == "", out   # not the list without its default line
    assert len(err.strip().splitlines()) == 1 and "$DFTL_WARP_DEVICE=bogus" in err and "Traceback" not in err
