"""The applications built on the library: the command line, benchmarks, soak and demo.

``pour-gym`` (:mod:`~pour_gym.apps.cli`, its subcommands in
:mod:`~pour_gym.apps.commands`), the benchmarks (:mod:`~pour_gym.apps.bench`), the
random-action soak (:mod:`~pour_gym.apps.soak`), the demo (:mod:`~pour_gym.apps.demo`) and
the sensors' pictures (:mod:`~pour_gym.apps.sensor_pictures`).
Nothing in the library imports them.
"""
