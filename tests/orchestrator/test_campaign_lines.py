"""What ``jitterfmu campaign`` ends with: the numbers a user runs it for."""

from orchestrator.cli.campaign import wheel_lines

HEAD = ('"sweep","configuration","instrument","axis","metric","window","worst_rpm","unit",'
        '"value","requirement","margin"\n')


def test_a_wheel_sweep_ends_with_the_worst_speed_of_each_axis(tmp_path):
    path = tmp_path / "wheel_sweeps_worst.csv"
    path.write_text(HEAD
                    + '"RWA","off","SWIR","roll","peak_to_peak",1.8,3462.9,"arcsec",0.0694,'
                      '2.2,2.13\n'
                    + '"RWA","on","SWIR","roll","peak_to_peak",1.8,6000.0,"arcsec",0.0419,'
                      '2.2,2.16\n')
    assert wheel_lines(path) == [
        "worst wheel speed per axis (peak_to_peak over 1.8 s, arcsec; requirement in "
        "brackets):",
        "  SWIR roll: off 0.0694 at 3463 rpm | on 0.0419 at 6000 rpm  [2.2]"]


def test_no_sweep_file_gives_no_line(tmp_path):
    assert wheel_lines(tmp_path / "missing.csv") == []
    (tmp_path / "empty.csv").write_text(HEAD)
    assert wheel_lines(tmp_path / "empty.csv") == []
