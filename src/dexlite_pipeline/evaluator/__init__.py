"""The learned grasp evaluator in the pipeline: its on-generator examples, its training on a run's simulated grasps
and the ranking of the model's samples by it (the network itself: ``model.evaluator``)."""
