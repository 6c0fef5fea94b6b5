"""The stage library: every stage of every experiment, with the settings, the test protocol and
the helpers they share. An experiment (:mod:`mbn.experiments.registry`) is a composition of
these stages plus its report; no experiment imports another's modules.

- the reproduction's controllers: :mod:`.multiplier`, :mod:`.rf`, :mod:`.lf_search`,
  :mod:`.lf`, :mod:`.im`, :mod:`.pm` (:func:`.compose.controller_stages` lists them in order);
- their tests: :mod:`.tests` (the paper's protocol, jittered starts, held-out maze) and
  :mod:`.generalization` (generated mazes and the zero-shot suite);
- new behaviours: :mod:`.im_full`, :mod:`.programs`, :mod:`.mbn3`, :mod:`.tests3`,
  :mod:`.generalization3`;
- studies of them: :mod:`.noise_levels`, :mod:`.ablations`, :mod:`.contest`,
  :mod:`.contest3` (with :mod:`.monolithic`, the monolithic CTRNN contender);
- shared: :mod:`.settings` (the sections several stages read, the quick preset),
  :mod:`.protocol` (the test names and targets), :mod:`.common` (what the stages' code shares),
  :mod:`.keys` (every stage's random-stream number, one table).
"""
