"""The data loop (Dex1B's): rounds that sample with the last model, keep the new distinct grasps that hold, and retrain.

Round r >= 1 starts from round r-1's model (round 0's is the pipeline's ``results/model/cvae.pt``) and round r-1's
grasp set (round 0's: the lift-successful grasps of the training objects that model was trained on, ``initial_set``).
Per shard it samples ``loop.grasps_per_object`` grasps on every stable training object, those without any grasp yet
included (``sample_round``); the pipeline's post-optimization refines them (``post_optimize_round``); the equal energy
filter, the lift test and (``loop.six_directions``) the six-direction test validate them, on each object's table in
tabletop mode (``validate_round``). ``merge`` then keeps each validated grasp that is a new distinct grasp, and the
next model trains on the merged set, warm-started (``train_round``). Every candidate that is not kept carries one
``drop_reason`` (``round_basics.DROP_REASONS``). The same sampling, refinement and validation run each round's model
on the held-out objects with a small cap (``loop.heldout_grasps_per_object``): the held-out curve of the loop table
(``summary`` per round, ``table`` over rounds).

One module per step, each imported only by the stage that runs the step (``stages.loop_*``), so that a stage's code
hash (``codehash``) covers its own step; ``round_basics``, ``round_set`` and ``round_objects`` are what steps share.
"""
