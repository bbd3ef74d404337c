"""A generated curriculum, trained and summarised from Python, then a whole experiment.

    python examples/curriculum.py

Parallel jobs start fresh Python processes that import this file again, so a script that runs
experiments keeps its work under ``if __name__ == "__main__":`` (a notebook needs nothing).
"""

from c2inet import ContinualTrainer, ModelConfig, TrainConfig, get_method, summarise
from sim import Execution, ExperimentConfig, learner_tasks, run_experiment


def main() -> None:
    # 1. The learner on simulated domains: crowds at three noise levels, at small sizes.
    tasks = learner_tasks("crowd_noise_0.1..0.3", quick=True)
    method = get_method("ewc")(ModelConfig())
    result = ContinualTrainer(method, tasks, TrainConfig(epochs=2)).run()
    summary = summarise([result.matrices], [result.summaries])
    print("EWC, ADE averaged over seen tasks:", [round(v, 3) for v in summary["avg_seen_ade"]])

    # 2. The same as `python -m sim.run`: every output in a fresh folder under runs/.
    config = ExperimentConfig("crowd_noise_0.1..0.3", methods=("finetune", "cv"), quick=True)
    metrics = run_experiment(config, execution=Execution(jobs=2))
    print("fine-tune forgetting:", metrics["methods"]["finetune"]["forgetting_final_ade"])


if __name__ == "__main__":
    main()
