"""Interaction on top of the wall hit: smoothing, pointing events, gestures, commands, hand poses, TUIO.

The report frames the pointer as the first stage of a gesture interpretation
system (section 2, Figure 1: analysis, recognition, a grammar of commands);
this package is that system's later stages (docs/interaction.md):

* ``smoothing.py``   the One Euro filter on wall hits;
* ``strokes.py``     the hit's trajectory cut into strokes between pauses;
* ``recognizer.py``  $1-family template matching of strokes (pure functions);
* ``templates.py``   gesture templates as JSON data, shipped (``templates/``) and recorded;
* ``engine.py``      one pointer's smoothing, enter/leave, dwell and gestures, fed capture times;
* ``grammar.py``     events and gestures to named commands;
* ``hand.py``        hand poses: extended fingers counted in one camera's image (section 3.9);
* ``tuio.py``        the TUIO 1.1 cursor output over OSC/UDP;
* ``extension.py``   all of it as a pipeline extension of the daemon;
* ``scripted.py``    simulated hit trajectories with known gestures (tests, benchmark, built-in templates).
"""
