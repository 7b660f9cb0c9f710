"""Register map of the BSS HD-Lock 102000.X door lock.

Transcribed from the vendor document (German), section 3: 3.1 input registers,
3.2 holding registers with 3.2.1-3.2.8. Decisions on ambiguities follow
SPEC-NOTES.md ("HD-Lock"); each is cited in a one-line comment where it is taken.
Holding-register writes are volatile until the Save-Settings command (section 4.1).
The value tables and bit fields the registers name are in :mod:`devices.hdlock.tables`.
"""

from __future__ import annotations

from devices.hdlock.tables import (  # the value tables and bit fields the map names (importable from here too)
    BAUDRATES, DIRECTION, DOOR_IGNORED_SOURCES, DOOR_IGNORED_WARNING, DOOR_STATE, HALL_FIELDS, LOCK_REQUEST,
    LOCK_REQUEST_SOURCE, LOCK_STATE, LOCK_STATUS_BITS, MOTOR_RESULT, MOTOR_STATE_IR3, MOTOR_STATE_IR53,
    OUTPUT_FUNCTION, PARITY, REMOVE_MAGNET, REMOVE_MAGNET_WARNING, STATE_MACHINE_STATE, STOP_BITS,
    SYSTEM_CORE_CLOCK_CONFIG_FIELDS, ZERO_POSITION_WHEN_UNLOCKED,
)
from devices.message import Message, N_
from devices.params import Access, Param, ParamMap

# Section 3.1 prints no unit for inputs 10, 60, 61 (elapsed times); every other time of the map is in ms (3.2): ms taken.
ELAPSED_UNIT = "ms"
ELAPSED_TOP = 0xFFFF  # section 3.1 does not say whether the count stops or wraps at the register's top: named, not a time


class ElapsedParam(Param):
    """An elapsed time of section 3.1: ms, and the register's top value named as such."""

    def display(self, raw: int) -> str:
        if raw == ELAPSED_TOP:
            return f"{ELAPSED_TOP} {ELAPSED_UNIT} (at its top: 65.5 s or more)"
        return super().display(raw)

INPUT = "input"
HOLDING = "holding"

# Holding 3004/3006 (thresholds) and 3007/3008 (offsets) are compared with, and shift, the magnet position that
# input 7 "Calculated proxi (normalized)" and holding 1005 give in [Inc] (sections 3.1, 3.2, 3.2.7, 3.2.8).
PROXIMITY_UNIT = "Inc"


def _command_register(name: str, address: int, description: str) -> Param:
    """One of holding 2000-2003, the parameters and the ID of a system command (section 4): default 0, written only
    by the system-command path, never as a parameter."""
    return Param(name, HOLDING, address, Access.RW, never_write=True, default=0, description=description)


# -- the register map ---------------------------------------------------------------------

_INPUTS: list[Param] = [
    Param(
        "LockState", INPUT, 0, Access.R,
        enum=LOCK_STATE,
        description=N_("Current locking state: 0 = unlocked (bolt retracted), "
            "1 = locked (bolt extended). (section 3.1)"),
    ),
    Param(
        "LockRequest", INPUT, 1, Access.R,
        enum=LOCK_REQUEST,
        description=N_("Current lock request: 0 = lock request inactive, "
            "1 = lock request active. (section 3.1)"),
    ),
    Param(
        "BoltPosition", INPUT, 2, Access.R, unit="Inc",
        description=N_("Current bolt position: 0 (retracted) to about 115 "
            "(approx. maximum when extended). (section 3.1)"),
    ),
    Param(
        "MotorState", INPUT, 3, Access.R,
        enum=MOTOR_STATE_IR3,
        description=N_("Current direction of motor travel: 0 = inactive, 1 = extending, "
            "2 = retracting, 3 = braking. (section 3.1)"),
    ),
    Param(
        "MotorSpeed", INPUT, 4, Access.R,
        description=N_("Current travel speed of the motor. (section 3.1)"),
    ),
    Param(
        "ValueHallSensor1", INPUT, 5, Access.R,
        description=N_("Current value of hall sensor 1. (section 3.1)"),
    ),
    Param(
        "ValueHallSensor2", INPUT, 6, Access.R,
        description=N_("Current value of hall sensor 2. (section 3.1)"),
    ),
    Param(
        "Calculated proxi (normalized)", INPUT, 7, Access.R, unit="Inc",
        description=N_("Magnet position calculated from the values of hall sensor 1 and "
            "hall sensor 2; compared with the proximity thresholds (sections 3.1, 3.2.7)."),
    ),
    Param(
        "DoorState", INPUT, 8, Access.R,
        enum=DOOR_STATE,
        description=N_("Current door state: 0 = undefined, 1 = door open, 2 = door closing, "
            "3 = door closed. (section 3.1)"),
    ),
    Param(
        "StateMachineState", INPUT, 9, Access.R,
        enum=STATE_MACHINE_STATE,
        description=N_("Current state of the state machine: 0 = start, 1 = referencing, "
            "2 = unlocked, 3 = locking, 4 = locked, 5 = unlocking, 6 = error locked, "
            "7 = error locking, 8 = error locking pause short, 9 = error locking pause long, "
            "10 = error locking waiting, 11 = error unlocked, 12 = error unlocking. (section 3.1)"),
    ),
    ElapsedParam(
        "StateMachineElapsed", INPUT, 10, Access.R, unit=ELAPSED_UNIT,
        description=N_("Time elapsed since the last change of StateMachineState (input 9); "
            "no unit printed, ms taken like the other times; 65535 = the register's top. (section 3.1)"),
    ),
    Param(
        "Direction", INPUT, 11, Access.R,
        signed=True,  # int16, -1/0/1 (section 3.1, 3.2.5; SPEC-NOTES signed registers)
        enum=DIRECTION,
        description=N_("Current opening direction: -1 = always right-hinged, 0 = automatic mode, "
            "1 = always left-hinged. (sections 3.1, 3.2.5)"),
    ),
    Param(
        "RetryLockCounter", INPUT, 12, Access.R,
        description=N_("Number of locking or unlocking attempts in which the bolt could not "
            "extend/retract properly. (section 3.1)"),
    ),
    Param(
        "RetryUnlockCounter", INPUT, 13, Access.R,
        description=N_("Retry counter for unlocking; the document only says 'set via holding "
            "registers 32/33' (Lock/UnlockInterval1/2). (section 3.1)"),
    ),
    Param(
        "SystemCoreClock", INPUT, 14, Access.R, unit="MHz",
        description=N_("Current clock frequency of the microcontroller. (section 3.1)"),
    ),
    Param(
        "SystemCoreClock-Config", INPUT, 15, Access.R,
        fields=SYSTEM_CORE_CLOCK_CONFIG_FIELDS,
        description=N_("Current clock source: bit 0 HSI ready (internal oscillator), bit 1 HSE "
            "ready (external oscillator), bit 2 PLL ready, bit 3 0 = HSI active / 1 = HSE active, "
            "bits 4-5 system clock source 0 = HSI, 1 = HSE, 2 = PLL. (section 3.1)"),
    ),
    Param(
        # int16 like the thresholds it mirrors (section 3.2.7)
        "SelectedThreshold", INPUT, 16, Access.R, signed=True,
        description=N_("Proximity threshold currently in use; must equal either "
            "SettingsProximityThresholdUnlock (holding 3004) or SettingsProximityThresholdLock "
            "(holding 3006). (section 3.1)"),
    ),
    Param(
        "ActS", INPUT, 50, Access.R, unit="#",
        description=N_("Current motor position. (section 3.1)"),
    ),
    Param(
        "ActV", INPUT, 51, Access.R, unit="#/s",
        signed=True,  # int16: negative while the bolt moves in (issue 26.8; SPEC-NOTES signed registers)
        description=N_("Current motor speed (set value). (section 3.1)"),
    ),
    Param(
        "MeasuredV", INPUT, 52, Access.R, unit="#/s",
        signed=True,  # int16: negative while the bolt moves in (issue 26.8; SPEC-NOTES signed registers)
        description=N_("Measured motor speed. (section 3.1)"),
    ),
    Param(
        "MotorState", INPUT, 53, Access.R,
        label="MotorState (IR53)",
        signed=True,  # int16, -1..4 (section 3.1; SPEC-NOTES signed registers)
        enum=MOTOR_STATE_IR53,
        description=N_("Current motor state: -1 = inactive, 0 = forward, 1 = backward, "
            "2 = braked, 3 = last state, 4 = active. (section 3.1)"),
    ),
    Param(
        "MotorResult", INPUT, 54, Access.R,
        enum=MOTOR_RESULT,
        description=N_("Reason for the last motor stop: None, AtPos, MinSpeed, Timeout, "
            "userStop, OutStageDisabled, Currentlimit (printed without numbers; numbered "
            "0-6 in printed order as an assumption). (section 3.1)"),
    ),
    Param(
        "ActPWM", INPUT, 55, Access.R, unit="%",
        description=N_("Currently active PWM. (section 3.1)"),
    ),
    Param(
        "VoltageAtMotorclamps", INPUT, 56, Access.R, unit="V",
        description=N_("Current voltage at the motor (VCC * PWM). (section 3.1)"),
    ),
    Param(
        "ActCurrent", INPUT, 57, Access.R, unit="mA",
        description=N_("Current motor current. (section 3.1)"),
    ),
    Param(
        "MaxMotorCurrent", INPUT, 58, Access.R, unit="mA",
        description=N_("Maximum motor current. (section 3.1)"),
    ),
    Param(
        "ErrVsum", INPUT, 59, Access.R,
        signed=True,  # int16: the integral part of a controller swings both ways (SPEC-NOTES signed registers)
        description=N_("Integral part of the speed controller. (section 3.1)"),
    ),
    ElapsedParam(
        "Time since last change", INPUT, 60, Access.R, unit=ELAPSED_UNIT,
        description=N_("Time elapsed since the motor state last changed; no unit printed, ms "
            "taken like the other times; 65535 = the register's top. (section 3.1)"),
    ),
    ElapsedParam(
        "Last time since last change", INPUT, 61, Access.R, unit=ELAPSED_UNIT,
        description=N_("Previous value of 'Time since last change' (input 60; the document "
            "says 'holding register 60'). (section 3.1)"),
    ),
    Param(
        "SupplyVoltage", INPUT, 62, Access.R, unit="V",
        description=N_("Current supply voltage. (section 3.1)"),
    ),
    Param(
        "ActCurrent", INPUT, 63, Access.R, unit="mA",
        label="ActCurrent (IR63)",
        description=N_("Current motor current (printed a second time, see input 57). (section 3.1)"),
    ),
    Param(
        "FirmwareVersion", INPUT, 100, Access.R,
        description=N_("Current firmware version as a decimal number in 16 bits. (section 3.1)"),
    ),
    Param(
        "SavedSettings", INPUT, 101, Access.R,
        description=N_("Number of times the settings memory was written; incremented each "
            "time the Save-Settings command is executed. (section 3.1)"),
    ),
    Param(
        "BootloaderVersion", INPUT, 102, Access.R,
        description=N_("Current bootloader version. (section 3.1)"),
    ),
    Param(
        "HardwareVersion", INPUT, 103, Access.R,
        description=N_("Current hardware version. (section 3.1)"),
    ),
    Param(
        "SerialNumber", INPUT, 104, Access.R,
        words=2,  # 32 bit: input 104 = high word, 105 = low word (section 3.1; SPEC-NOTES)
        description=N_("Serial number / device ID, 32 bit = (HighWord << 16) | LowWord, "
            "input 104 = high word, 105 = low word. Example: 0x000A, 0x1234 -> 0x000A1234 "
            "= 660020. (section 3.1)"),
    ),
]

_HOLDINGS: list[Param] = [
    Param(
        "SettingsRevision", HOLDING, 0, Access.MFR,
        never_write=True,  # SPEC-NOTES: never written by the GUI
        description=N_("Settings memory change: number of times the settings were saved. "
            "Changing it acts as a command: decrement by 1 = factory settings, 0 = load from "
            "flash, increment by 1 = save to flash. (section 3.2)"),
    ),
    Param(
        "BoltPosition", HOLDING, 2, Access.RO, unit="Inc",
        label="BoltPosition (HR2)",
        description=N_("Current position of the motor: 0 (retracted) to about 115 (approx. "
            "maximum when extended); same as holding 1001. (section 3.2)"),
    ),
    Param(
        "ZeroPositionWhenUnlocked", HOLDING, 3, Access.RO,
        enum=ZERO_POSITION_WHEN_UNLOCKED,
        description=N_("Shows whether the bolt position is zeroed automatically when the bolt "
            "has retracted: 0 = no, 1 = yes. (section 3.2)"),
    ),
    Param(
        "LockRequestSource", HOLDING, 4, Access.RW,
        label="LockRequestSource (HR4)",
        enum=LOCK_REQUEST_SOURCE,
        default=4,
        confirm=DOOR_IGNORED_WARNING,
        confirm_values=DOOR_IGNORED_SOURCES,
        description=N_("The source the lock uses for the bolt (reported in the CAN status "
            "frame, section 6.5.1; set by cmdSetLockRequestSource, 6.6.1.1). Values as holding "
            "1002: 0x00-0x07 lock when the condition AND the door is closed, 0x80-0x87 the same "
            "condition with the door ignored. Factory 0x04 IrsNotLine. (sections 3.2, 3.2.2)"),
    ),
    Param(
        "LockTargetPosition", HOLDING, 10, Access.MFR, unit="Inc",
        description=N_("Target position the bolt should reach when locking. (section 3.2)"),
    ),
    Param(
        "LockOkPosition", HOLDING, 11, Access.MFR, unit="Inc",
        description=N_("Position from which the lock counts as locked. (section 3.2)"),
    ),
    Param(
        "LockTargetSpeed", HOLDING, 12, Access.MFR, unit="#/s",
        description=N_("Travel speed to be reached when locking. (section 3.2)"),
    ),
    Param(
        "LockAcceleration", HOLDING, 13, Access.MFR, unit="#/s²",
        description=N_("Acceleration when extending the bolt from standstill to travel speed. "
            "(section 3.2)"),
    ),
    Param(
        "LockDeceleration", HOLDING, 14, Access.MFR, unit="#/s²",
        description=N_("Deceleration when extending the bolt, shortly before it reaches the OK "
            "position. (section 3.2)"),
    ),
    Param(
        "LockHoldingPWM", HOLDING, 15, Access.MFR,
        description=N_("PWM with which the motor is driven to hold the bolt in position "
            "(locked). (section 3.2)"),
    ),
    Param(
        "LockMaximumTime", HOLDING, 16, Access.MFR, unit="ms",
        description=N_("Maximum locking time, measured from the input signal until the bolt "
            "reaches its OK position. (section 3.2)"),
    ),
    Param(
        "LockMaximumCurrent", HOLDING, 17, Access.MFR, unit="ADC#",
        description=N_("Maximum current when locking. (section 3.2)"),
    ),
    Param(
        "LockMinimumSpeed", HOLDING, 18, Access.MFR, unit="#/s",
        description=N_("Minimum speed when locking. (section 3.2)"),
    ),
    Param(
        "LockDisturbanceDelay", HOLDING, 19, Access.MFR, unit="ms",
        description=N_("Disturbance delay of the locking process. (section 3.2)"),
    ),
    Param(
        "UnlockTargetPosition", HOLDING, 20, Access.MFR, unit="Inc",
        description=N_("Target position the bolt should reach when unlocking. (section 3.2)"),
    ),
    Param(
        "UnlockOkPosition", HOLDING, 21, Access.MFR, unit="Inc",
        description=N_("Position from which the lock counts as unlocked. (section 3.2)"),
    ),
    Param(
        "UnlockTargetSpeed", HOLDING, 22, Access.MFR, unit="#/s",
        description=N_("Travel speed to be reached when unlocking. (section 3.2)"),
    ),
    Param(
        "UnlockAcceleration", HOLDING, 23, Access.MFR, unit="#/s²",
        description=N_("Acceleration when retracting the bolt from standstill to travel speed. "
            "(section 3.2)"),
    ),
    Param(
        "UnlockDeceleration", HOLDING, 24, Access.MFR, unit="#/s²",
        description=N_("Deceleration when retracting the bolt, shortly before it reaches the OK "
            "position. (section 3.2)"),
    ),
    Param(
        "UnlockHoldingPWM", HOLDING, 25, Access.MFR,
        description=N_("PWM with which the motor is driven to hold the bolt in position "
            "(unlocked). (section 3.2)"),
    ),
    Param(
        "UnlockMaximumTime", HOLDING, 26, Access.MFR, unit="ms",
        description=N_("Maximum unlocking time, measured from the input signal until the bolt "
            "reaches its OK position (the document prints 'locking time', as for 16). (section 3.2)"),
    ),
    Param(
        "UnlockMaximumCurrent", HOLDING, 27, Access.MFR, unit="ADC#",
        description=N_("Maximum current when unlocking. (section 3.2)"),
    ),
    Param(
        "UnlockMinimumSpeed", HOLDING, 28, Access.MFR, unit="#/s",
        description=N_("Minimum speed when unlocking. (section 3.2)"),
    ),
    Param(
        "UnlockDisturbanceDelay", HOLDING, 29, Access.MFR, unit="ms",
        description=N_("Disturbance delay of the unlocking process (the document prints "
            "'locking process', as for 19). (section 3.2)"),
    ),
    Param(
        "Lock/UnlockFailDelay1", HOLDING, 30, Access.MFR, unit="ms",
        description=N_("Time between locking and unlocking attempts (interval 1). (section 3.2)"),
    ),
    Param(
        "Lock/UnlockFailDelay2", HOLDING, 31, Access.MFR, unit="s",
        description=N_("Time between repetitions of interval 1 (interval 2). (section 3.2)"),
    ),
    Param(
        "Lock/UnlockInterval1", HOLDING, 32, Access.MFR,
        description=N_("Number of locking and unlocking attempts made at a spacing of "
            "Lock/UnlockFailDelay1 (holding 30). (section 3.2)"),
    ),
    Param(
        "Lock/UnlockInterval2", HOLDING, 33, Access.MFR,
        description=N_("Number of repetitions of interval 1 made at a spacing of "
            "Lock/UnlockFailDelay2 (holding 31). (section 3.2)"),
    ),
    Param(
        "SettingsOutput1", HOLDING, 40, Access.MFR,
        enum=OUTPUT_FUNCTION,
        description=N_("Function of output 1 (pin 1, brown wire): the state in which it "
            "switches high. Values as holding 3001. (section 3.2.4)"),
    ),
    Param(
        "SettingsOutput2", HOLDING, 41, Access.MFR,
        enum=OUTPUT_FUNCTION,
        description=N_("Function of output 2 (pin 3, white wire): the state in which it "
            "switches high. Values as holding 3002. (section 3.2.4)"),
    ),
    Param(
        "Baudrate", HOLDING, 100, Access.MFR,
        default=19200,
        extra={"valid_values": ", ".join(str(b) for b in BAUDRATES)},
        description=N_("Modbus baud rate. Valid values: 300, 1200, 4800, 9600, 14400, "
            "19200 (default), 38400, 56000, 57600. (section 3.2)"),
    ),
    Param(
        "Parity", HOLDING, 101, Access.MFR,
        enum=PARITY,
        default=2,
        description=N_("Modbus parity: 0 = none, 1 = odd, 2 = even (default). (section 3.2)"),
    ),
    Param(
        "StopBit", HOLDING, 102, Access.MFR,
        enum=STOP_BITS,
        default=1,
        description=N_("Number of Modbus stop bits: 0 = 0.5 bit, 1 = 1 bit (default), "
            "2 = 2.5 bit, 3 = 2 bit. (section 3.2)"),
    ),
    Param(
        "DeviceAddress", HOLDING, 103, Access.MFR,
        default=1,  # factory slave ID 1 (sections 2.2, 5)
        description=N_("Device (Modbus) address; can only be changed with the Set Modbus "
            "Address command via holding 2000-2003. Factory 1. (sections 3.2, 4.3)"),
    ),
    Param(
        "LockStatus", HOLDING, 1000, Access.RO,
        fields=LOCK_STATUS_BITS,
        description=N_("Status as 16 bits: 0 LockRequest, 1 ProximityInPlace, 2 DoorInPosition, "
            "3 ProximityOverrange, 4 LockRequest, 7 ForceActive, 8 BoltLocked, 9 BoltUnlocked, "
            "10 BoltMovingOut, 11 BoltMovingIn. (section 3.2.1)"),
    ),
    Param(
        "BoltPosition", HOLDING, 1001, Access.RO, unit="Inc",
        label="BoltPosition (HR1001)",
        description=N_("Current position of the motor: 0 (retracted) to about 115 (approx. "
            "maximum when extended); same as holding 2. (section 3.2)"),
    ),
    Param(
        "LockRequestSource", HOLDING, 1002, Access.RW,
        enum=LOCK_REQUEST_SOURCE,
        default=4,
        confirm=DOOR_IGNORED_WARNING,
        confirm_values=DOOR_IGNORED_SOURCES,
        description=N_("Conditions under which the bolt extends. 0x00-0x07: condition 1 AND "
            "door closed; 0x80-0x87: condition 1 only (door ignored). Condition 1: IrsNever "
            "never, IrsAlways always, IrsOverrange hall sensors overdriven, IrsLine input "
            "inactive (<4 V), IrsNotLine input active (>10 V, factory 0x04), "
            "IrsToggleOnLineEdge/PEdge/NEdge any/positive/negative edge on the LOCK-REQUEST "
            "input. A register of its own: the source the lock reports as in use is holding 4. "
            "(sections 3.2.2, 6.5.1)"),
    ),
    Param(
        "MaximumTimeUnlock", HOLDING, 1003, Access.RW, unit="ms",
        minimum=0, maximum=65535, device_updates=True,  # the lock measures it at every cycle
        description=N_("Longest time measured so far that the bolt needed to unlock. "
            "(section 3.2)"),
    ),
    Param(
        "MaximumTimeLock", HOLDING, 1004, Access.RW, unit="ms",
        minimum=0, maximum=65535, device_updates=True,  # the lock measures it at every cycle
        description=N_("Longest time measured so far that the bolt needed to lock. (section 3.2)"),
    ),
    Param(
        "ValueProximityThreshold", HOLDING, 1005, Access.RO, unit="Inc",
        description=N_("Magnet position calculated from the values of hall sensor 1 and hall "
            "sensor 2. (section 3.2)"),
    ),
    Param(
        "Hall", HOLDING, 1006, Access.RO,
        fields=HALL_FIELDS,
        description=N_("Analogue values of the hall sensors: high byte H1 = 8-bit value of "
            "sensor 1, low byte H2 = 8-bit value of sensor 2. (section 3.2)"),
    ),
    Param(
        "Temperatur", HOLDING, 1007, Access.RO, unit="°C",
        description=N_("Temperature measured by the CPU. (section 3.2)"),
    ),
    Param(
        "Voltage", HOLDING, 1008, Access.RO, unit="mV",
        description=N_("Supply voltage. (section 3.2)"),
    ),
    Param(
        "MotorCurrent", HOLDING, 1009, Access.RO, unit="mA",
        description=N_("Current motor current. (section 3.2)"),
    ),
    Param(
        "MaxMotorCurrent", HOLDING, 1010, Access.RO, unit="mA",
        label="MaxMotorCurrent (HR1010)",
        description=N_("Maximum motor current. (section 3.2)"),
    ),
    _command_register(
        "Parameter 0", 2000,
        Message(N_(
            "Parameter 0 of a system command (Set Modbus Address: new address). "
            "Default 0. (sections 3.2, 4)"
        )),
    ),
    _command_register(
        "Parameter 1", 2001,
        Message(N_(
            "Parameter 1 of a system command (Set Modbus Address: selection mask "
            "of LockStatus bits). Default 0. (sections 3.2, 4)"
        )),
    ),
    _command_register(
        "Parameter 2", 2002,
        Message(N_(
            "Parameter 2 of a system command (Set Modbus Address: required states "
            "of the selected bits). Default 0. (sections 3.2, 4)"
        )),
    ),
    _command_register(
        "Command", 2003,
        Message(N_(
            "Command ID, written after parameters 0-2: 1 = Save-Settings, "
            "2 = Restore-Settings, 3 = Set Modbus Address. Default 0. (sections 3.2, 4)"
        )),
    ),
    Param(
        "LockRequestDelay", HOLDING, 3000, Access.RW, unit="ms",
        minimum=0, maximum=65535,
        default=200,
        description=N_("Delay before the bolt extends once the strike plate has been detected "
            "in locking position, to let the door settle. Factory 200 ms. (section 3.2.3)"),
    ),
    Param(
        "SettingOutput1", HOLDING, 3001, Access.RW,
        enum=OUTPUT_FUNCTION,
        default=4,
        description=N_("Function of output 1 (pin 1, brown wire): 0 always off, 1 always on, "
            "2 door closed, 3 door open, 4 bolt extended (factory), 5 bolt retracted, 6 lock "
            "request present, 7 no lock request, 8 blinking ~1 Hz, 10 hall sensors overdriven. "
            "(section 3.2.4)"),
    ),
    Param(
        "SettingOutput2", HOLDING, 3002, Access.RW,
        enum=OUTPUT_FUNCTION,
        default=2,
        description=N_("Function of output 2 (pin 3, white wire): 0 always off, 1 always on, "
            "2 door closed (factory), 3 door open, 4 bolt extended, 5 bolt retracted, 6 lock "
            "request present, 7 no lock request, 8 blinking ~1 Hz, 10 hall sensors overdriven. "
            "(section 3.2.4)"),
    ),
    Param(
        "SettingsDirection", HOLDING, 3003, Access.RW,
        signed=True,  # int16, -1/0/1 like input 11 (section 3.2.5)
        enum=DIRECTION,
        default=0,
        description=N_("Door opening direction: -1 = always right-hinged, 0 = automatic "
            "detection (factory), 1 = always left-hinged. A wrong setting can cause "
            "malfunction; in automatic mode the door must be opened and closed once after each "
            "restart. (section 3.2.5)"),
    ),
    Param(
        "SettingsProximityThresholdUnlock", HOLDING, 3004, Access.RW, unit=PROXIMITY_UNIT,
        signed=True,  # int16 two's complement, factory -30 (section 3.2.7)
        default=65506,
        description=N_("Switching point for 'door closed' while not locked (bolt retracted): "
            "the bolt extends only once strike plate and locking element are almost aligned. "
            "Factory -30; adjust if installation tolerances prevent reaching it. "
            "Negative values as 16-bit two's complement. (section 3.2.7)"),
    ),
    Param(
        "SettingsRemoveMagnet", HOLDING, 3005, Access.RW,
        enum=REMOVE_MAGNET,
        default=0,
        confirm=REMOVE_MAGNET_WARNING,
        confirm_values=(1,),
        description=N_("Bolt retraction when the magnetic field changes: 0 = off (factory; an "
            "extended bolt stays out when the field weakens), 1 = bolt retracts when the field "
            "weakens, despite a lock request. 1 is a security risk: the lock can be unlocked "
            "from outside by manipulation. (section 3.2.6)"),
    ),
    Param(
        "SettingsProximityThresholdLock", HOLDING, 3006, Access.RW, unit=PROXIMITY_UNIT,
        signed=True,  # int16 two's complement, factory -60 (section 3.2.7)
        default=65476,
        description=N_("Switching point for 'door closed' while locked (bolt extended): a wider "
            "range so handle operation or rattling still counts as closed; leaving it may mean "
            "a forced opening attempt. Factory -60. Negative values as 16-bit two's complement. "
            "(section 3.2.7)"),
    ),
    Param(
        "SettingsProximityOffsetLeft", HOLDING, 3007, Access.RW, unit=PROXIMITY_UNIT,
        signed=True,  # int16 two's complement (section 3.2.8)
        description=N_("Offset for left-hinged doors (see Direction, input 11): fine adjustment "
            "of the strike plate position for special cases; positive shifts the zero line in "
            "opening direction. Negative values as 16-bit two's complement. (section 3.2.8)"),
    ),
    Param(
        "SettingsProximityOffsetRight", HOLDING, 3008, Access.RW, unit=PROXIMITY_UNIT,
        signed=True,  # int16 two's complement (section 3.2.8)
        description=N_("Offset for right-hinged doors (see Direction, input 11): fine adjustment "
            "of the strike plate position for special cases; positive shifts the zero line in "
            "opening direction. Negative values as 16-bit two's complement. (section 3.2.8)"),
    ),
    Param(
        "FwUpdateCommandRegister", HOLDING, 32770, Access.RW,
        never_write=True,  # firmware update: never sent by the GUI (SPEC-NOTES)
        description=N_("Triggers a restart for a firmware update: 1 = reset. (section 3.2)"),
    ),
]

PARAMS = ParamMap(_INPUTS + _HOLDINGS)
