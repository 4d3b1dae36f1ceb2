"""A recording stand-in of the ``RPi.GPIO`` module (the only part of a Pi we fake).

It has the real module's API (``setmode``, ``setup(pin, OUT, initial=...)``,
``output``, ``PWM(pin, freq)`` with ``start``/``ChangeDutyCycle``/
``ChangeFrequency``/``stop``, ``cleanup(pins)``) and enforces its rules (mode
set first, output only on pins set up as outputs, duty 0..100, one PWM per
pin), records every call, and keeps each pin's state, so tests assert the
L298N truth table on the pins. Input pins (``setup(pin, IN, pull_up_down=...)``)
rest at their pull level; a test drives them with :meth:`RecordingGPIO.drive_input`,
and ``add_event_detect`` callbacks run on one callback thread of their own, as
the real module's do. Use a fresh :class:`RecordingGPIO` per test;
``install()`` puts one on ``sys.modules`` as ``RPi.GPIO`` for code that
imports the real module.
"""

import queue
import sys
import threading
import types

BCM, BOARD = 11, 10
OUT, IN = 0, 1
HIGH, LOW = 1, 0
PUD_OFF, PUD_DOWN, PUD_UP = 20, 21, 22
RISING, FALLING, BOTH = 31, 32, 33


class RecordingGPIO:
    """One simulated Pi header: pin levels, PWM duties, and the call log."""

    BCM, BOARD, OUT, IN, HIGH, LOW = BCM, BOARD, OUT, IN, HIGH, LOW
    PUD_OFF, PUD_DOWN, PUD_UP = PUD_OFF, PUD_DOWN, PUD_UP
    RISING, FALLING, BOTH = RISING, FALLING, BOTH

    def __init__(self):
        self.calls = []  # ("setup", pin, ...), ("output", pin, level), ("pwm_start", pin, duty), ...
        self.mode = None
        self.outputs = {}  # pin -> level, for pins set up as outputs
        self.pwms = {}  # pin -> running PWM
        self.fail_on = None  # name of a call that raises RuntimeError (to test the exception path)
        self.cleaned = []
        self.inputs = {}  # pin -> level its pull resistor gives, for pins set up as inputs
        self.driven = {}  # pin -> level something outside (a button) holds it at; wins over the pull
        self.detects = {}  # pin -> (edge, callback)
        self._events = None  # the callback thread's queue while an event detection exists
        self._event_thread = None

    def _record(self, *call):
        self.calls.append(call)
        if self.fail_on == call[0]:
            raise RuntimeError("stand-in GPIO failure in {}".format(call[0]))

    def setwarnings(self, flag):
        self._record("setwarnings", flag)

    def getmode(self):
        return self.mode

    def setmode(self, mode):
        self._record("setmode", mode)
        if self.mode is not None and self.mode != mode:
            raise ValueError("A different mode has already been set!")
        self.mode = mode

    def setup(self, channel, direction, pull_up_down=PUD_OFF, initial=-1):
        self._need_mode()
        if direction == IN:
            self._record("setup", channel, direction, pull_up_down)
            self.inputs[channel] = HIGH if pull_up_down == PUD_UP else LOW
            return
        self._record("setup", channel, direction, initial)
        if direction == OUT:
            self.outputs[channel] = HIGH if initial == HIGH else LOW

    def output(self, channel, value):
        self._need_mode()
        self._record("output", channel, value)
        if channel not in self.outputs:
            raise RuntimeError("The GPIO channel has not been set up as an OUTPUT")
        self.outputs[channel] = HIGH if value else LOW

    def input(self, channel):
        if channel in self.inputs:
            return self.driven.get(channel, self.inputs[channel])
        return self.outputs.get(channel, LOW)

    def add_event_detect(self, channel, edge, callback=None, bouncetime=None):
        self._record("add_event_detect", channel, edge, bouncetime)
        if channel not in self.inputs:
            raise RuntimeError("You must setup() the GPIO channel as an input first")
        if channel in self.detects:
            raise RuntimeError("Conflicting edge detection already enabled for this GPIO channel")
        self.detects[channel] = (edge, callback)
        if self._events is None:
            self._events = queue.Queue()
            self._event_thread = threading.Thread(target=self._run_callbacks, args=(self._events,),
                                                  name="gpio-callbacks", daemon=True)
            self._event_thread.start()

    def remove_event_detect(self, channel):
        self._record("remove_event_detect", channel)
        self.detects.pop(channel, None)
        if not self.detects and self._events is not None:
            self._events.put(None)
            if self._event_thread is not threading.current_thread():
                self._event_thread.join(5)
            self._events = self._event_thread = None

    def _run_callbacks(self, events):
        while True:
            event = events.get()
            if event is None:
                return
            callback, channel = event
            callback(channel)

    def cleanup(self, channel=None):
        self._record("cleanup", channel)
        if channel is None:
            pins = list(self.outputs) + list(self.inputs)
        else:
            pins = [channel] if isinstance(channel, int) else list(channel)
        for pin in pins:
            if pin in self.detects:
                self.remove_event_detect(pin)
            self.outputs.pop(pin, None)
            self.inputs.pop(pin, None)
            self.pwms.pop(pin, None)
            self.cleaned.append(pin)

    def PWM(self, channel, frequency):  # noqa: N802 (the real module's name)
        if channel not in self.outputs:
            raise RuntimeError("You must setup() the GPIO channel as an output first")
        if channel in self.pwms:
            raise RuntimeError("A PWM object already exists for this GPIO channel")
        pwm = _PWM(self, channel, frequency)
        self.pwms[channel] = pwm
        return pwm

    def _need_mode(self):
        if self.mode is None:
            raise RuntimeError("Please set pin numbering mode using GPIO.setmode(GPIO.BOARD) or GPIO.setmode(GPIO.BCM)")

    # what tests ask ------------------------------------------------------------

    def drive_input(self, pin, level):
        """Hold a pin at ``level`` from outside (a button, a glitch); edge callbacks run as on a Pi."""
        old = self.input(pin)
        self.driven[pin] = level
        edge, callback = self.detects.get(pin, (None, None))
        if callback is None or old == level:
            return
        if edge == BOTH or (edge == FALLING and level == LOW) or (edge == RISING and level == HIGH):
            self._events.put((callback, pin))

    def level(self, pin):
        """The pin's level now, as the bridge sees it (a PWM pin: its duty in %)."""
        pwm = self.pwms.get(pin)
        if pwm is not None and pwm.running:
            return pwm.duty
        return self.outputs.get(pin, LOW)

    def duty(self, pin):
        """Duty in % of the running PWM on ``pin`` (0 when stopped)."""
        pwm = self.pwms.get(pin)
        return pwm.duty if pwm is not None and pwm.running else 0.0


class _PWM:
    """Software PWM on one pin, as ``GPIO.PWM`` returns."""

    def __init__(self, gpio, channel, frequency):
        self.gpio, self.channel, self.frequency = gpio, channel, frequency
        self.duty = 0.0
        self.running = False
        gpio._record("pwm", channel, frequency)

    def start(self, dutycycle):
        self._check(dutycycle)
        self.gpio._record("pwm_start", self.channel, dutycycle)
        self.duty, self.running = float(dutycycle), True

    def ChangeDutyCycle(self, dutycycle):  # noqa: N802
        self._check(dutycycle)
        self.gpio._record("pwm_duty", self.channel, dutycycle)
        self.duty = float(dutycycle)

    def ChangeFrequency(self, frequency):  # noqa: N802
        self.gpio._record("pwm_frequency", self.channel, frequency)
        self.frequency = frequency

    def stop(self):
        self.gpio._record("pwm_stop", self.channel)
        self.running = False
        self.duty = 0.0
        self.gpio.outputs[self.channel] = LOW

    @staticmethod
    def _check(dutycycle):
        if not 0.0 <= dutycycle <= 100.0:
            raise ValueError("dutycycle must have a value from 0.0 to 100.0")


def install(monkeypatch, gpio=None):
    """Make ``import RPi.GPIO`` give ``gpio`` (a fresh RecordingGPIO by default) for one test."""
    gpio = gpio or RecordingGPIO()
    module = types.ModuleType("RPi.GPIO")
    for name in dir(gpio):
        if not name.startswith("_"):
            setattr(module, name, getattr(gpio, name))
    package = types.ModuleType("RPi")
    package.GPIO = module
    monkeypatch.setitem(sys.modules, "RPi", package)
    monkeypatch.setitem(sys.modules, "RPi.GPIO", module)
    return gpio
