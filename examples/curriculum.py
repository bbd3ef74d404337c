"""A generated curriculum, trained and summarised from Python, method against method.

    python examples/curriculum.py

The whole experiment of ``python -m sim.run`` (every output in a run folder) is one call,
``sim.run_experiment``: the README's "From Python" shows it.
"""

from c2inet import ContinualTrainer, ModelConfig, TrainConfig, get_method, summarise
from sim import learner_tasks


def main() -> None:
    # The learner on simulated domains: crowds at three noise levels, at small sizes.
    tasks = learner_tasks("crowd_noise_0.1..0.3", quick=True)
    for name in ("finetune", "ewc"):
        result = ContinualTrainer(
            get_method(name)(ModelConfig()), tasks, TrainConfig(epochs=2)
        ).run()
        summary = summarise([result.matrices], [result.summaries])
        print(
            f"{name}, ADE averaged over seen tasks:", [round(v, 3) for v in summary["avg_seen_ade"]]
        )


if __name__ == "__main__":
    main()
