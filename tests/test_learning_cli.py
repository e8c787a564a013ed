"""The ``gfcs train`` subcommand: option parsing, resume rules, and an end-to-end run on the Panda."""

from __future__ import annotations

import argparse
import json
from types import SimpleNamespace

import numpy as np
import pytest

from gfcs.errors import ConfigError
from gfcs.learning.cli import _config, _split_holdout, register, run_train


def parse(argv):
    parser = argparse.ArgumentParser(prog="gfcs")
    sub = parser.add_subparsers(dest="command")
    register(sub)
    return parser.parse_args(argv)


def test_register_defaults_are_the_papers():
    pytest.importorskip("torch")
    from gfcs.learning.train import TrainConfig

    args = parse(["train", "--generate", "box", "--out", "m.pt"])
    assert args.func is run_train and args.generate == ["box"] and args.out == "m.pt"
    cfg = _config(args)
    assert cfg == TrainConfig()
    assert (cfg.passes, cfg.n_train, cfg.buffer_size, cfg.top_m, cfg.hidden) == (2, 25, 200, 4, (800, 800, 800))
    assert cfg.encoder.spacing == 0.15
    assert cfg.sampler_sgld().noise_scale == 1.0  # the sampler's SGLD at the paper's temperature (eq. 10-11)


def test_flags_reach_the_config():
    pytest.importorskip("torch")
    args = parse(["train", "--problems", "DIR", "--out", "m.pt", "--passes", "3", "--n-train", "10",
                  "--buffer", "50", "--top-m", "2", "--seed", "7", "--hidden", "64", "32", "--n-neg", "4",
                  "--n-uniform-neg", "0", "--batches", "2", "--population", "8", "--shuffle",
                  "--sample-noise", "0.5"])
    cfg = _config(args)
    assert cfg.sample_noise == 0.5 and cfg.sampler_sgld().noise_scale == 0.5
    assert (cfg.passes, cfg.n_train, cfg.buffer_size, cfg.top_m, cfg.seed) == (3, 10, 50, 2, 7)
    assert cfg.hidden == (64, 32) and cfg.n_neg == 4 and cfg.n_uniform_neg == 0 and cfg.shuffle
    assert cfg.solve == {"method": "gfcs", "batches": 2, "population": 8}
    with_config = _config(parse(["train", "--problems", "D", "--out", "m.pt", "--config", "fabric.toml"]))
    assert with_config.solve["fabric_config"] == "fabric.toml"
    with pytest.raises(ConfigError, match="n_train"):
        _config(parse(["train", "--problems", "D", "--out", "m.pt", "--n-train", "0"]))


def test_holdout_takes_the_last_problems_of_each_class():
    problems = [SimpleNamespace(name=f"{c}/{i}", cls=c) for c in ("box", "cage") for i in range(4)]
    train_set, held = _split_holdout(problems, 1)
    assert [p.name for p in held] == ["box/3", "cage/3"]
    assert [p.name for p in train_set] == ["box/0", "box/1", "box/2", "cage/0", "cage/1", "cage/2"]
    assert _split_holdout(problems, 0) == (problems, [])
    with pytest.raises(ConfigError, match="'box' has only 4"):
        _split_holdout(problems, 4)
    with pytest.raises(ConfigError, match="expected >= 0"):
        _split_holdout(problems, -1)


def test_resume_keeps_the_checkpoint_config(tmp_path):
    torch = pytest.importorskip("torch")
    from gfcs.learning.train import train
    from test_learning_train import ToySolver, make_problems, small_config

    torch.set_num_threads(1)
    ck = tmp_path / "run.ckpt.pt"
    train(make_problems(4), config=small_config(n_neg=3), solve_fn=ToySolver(), checkpoint=ck, progress=False,
          stop_after=2)
    cfg = _config(parse(["train", "--problems", "D", "--out", "m.pt", "--resume", str(ck), "--passes", "5"]))
    assert cfg.n_neg == 3 and cfg.passes == 5 and cfg.seed == small_config().seed
    with pytest.raises(ConfigError, match="n_neg"):
        _config(parse(["train", "--problems", "D", "--out", "m.pt", "--resume", str(ck), "--n-neg", "8"]))
    with pytest.raises(ConfigError, match="solve options"):
        _config(parse(["train", "--problems", "D", "--out", "m.pt", "--resume", str(ck), "--batches", "2"]))


def test_gfcs_train_end_to_end_then_solve_with_the_sampler(tmp_path):
    """Real solver and robot: 2 generated problems, one tiny training, then `gfcs solve --sampler`."""
    pytest.importorskip("torch")
    import gfcs
    from gfcs.cli import main
    from gfcs.learning.sampler import EBMSampler

    out = tmp_path / "model.pt"
    code = main(["train", "--generate", "bookshelf_small", "--n-problems", "3", "--holdout", "1", "--passes", "1",
                 "--n-train", "2", "--batches", "1", "--population", "6", "--epochs", "2", "--hidden", "16", "16",
                 "--n-neg", "4", "--out", str(out), "--no-progress", "--history", str(tmp_path / "h.json"),
                 "--plot", str(tmp_path / "curve.png")])
    assert code == 0 and out.exists() and (tmp_path / "model.ckpt.pt").exists()
    # --holdout 1: the third problem validates the uniform sampler and the one trained model
    history = json.loads((tmp_path / "h.json").read_text())
    assert [h["trainings"] for h in history if h["event"] == "validate"] == [0, 1]
    assert {h["problem"] for h in history if h["event"] == "solve"} == {"bookshelf_small/gen0_0000",
                                                                          "bookshelf_small/gen0_0001"}
    assert (tmp_path / "model.best.pt").exists() and (tmp_path / "curve.png").stat().st_size > 1000
    sampler = EBMSampler(out, device="cpu", sgld_config=None)
    robot = gfcs.Robot.panda()
    assert sampler.dof == robot.dof and sampler.robot["joint_names"] == list(robot.joint_names)
    from gfcs.generators import generate

    problem = generate("bookshelf_small", 1, seed=123)[0]
    y = sampler.sample(problem, 5, np.random.default_rng(0))
    assert y.shape == (5, robot.dof)
    assert np.all(y >= np.asarray(robot.lower)) and np.all(y <= np.asarray(robot.upper))
    code = main(["solve", "--sampler", str(out), "--batches", "1", "--population", "6",
                 "--json", str(tmp_path / "r.json")])
    assert code in (0, 1)  # 1 = solved without success; the point is that the sampler loads and runs
    assert "EBMSampler" in (tmp_path / "r.json").read_text()
    # --sgld-noise replaces the model file's sampler noise, and needs a model
    from gfcs.cli import _sampler, build_parser

    tuned = _sampler(build_parser().parse_args(["solve", "--sampler", str(out), "--sgld-noise", "0.7"]))
    assert tuned.sgld_config.noise_scale == 0.7 and sampler.sgld_config.noise_scale == 1.0
    assert tuned.sgld_config.iters == sampler.sgld_config.iters
    assert main(["solve", "--sampler", "uniform", "--sgld-noise", "0.7", "--batches", "1"]) == 2
    # a checkpoint passed as a model file is a clean user error (exit 2), not a traceback
    assert main(["solve", "--sampler", str(tmp_path / "model.ckpt.pt"), "--batches", "1"]) == 2


def test_learning_package_and_cli_work_without_torch():
    """torch is optional: blocking it must leave `gfcs.learning`, the encoding and `register` usable."""
    import subprocess
    import sys

    code = r"""
import sys
sys.modules["torch"] = None  # makes `import torch` fail as if it were not installed
import argparse
import gfcs.learning as L
from gfcs.learning.encoding import SceneEncoder
assert SceneEncoder().n_reference == 14 ** 3
parser = argparse.ArgumentParser()
L.register_cli(parser.add_subparsers())
try:
    L.EBMSampler
except ImportError as e:
    assert "pip install gfcs[learn]" in str(e), e
else:
    raise AssertionError("EBMSampler imported without torch")
print("ok")
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"


def test_negatives_default_to_the_papers_noise_and_the_variant_is_a_flag():
    pytest.importorskip("torch")
    from gfcs.learning.sgld import SGLDConfig

    assert SGLDConfig().noise_scale == 1.0
    assert _config(parse(["train", "--out", "m.pt"])).sgld.noise_scale == 1.0
    assert _config(parse(["train", "--out", "m.pt", "--negative-noise", "0.3"])).sgld.noise_scale == 0.3
