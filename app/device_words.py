"""The device vocabulary of the catalogs: the texts of the device types' tiles and the words of their live points
(states, flags, errors), marked here for ``pybabel extract`` since the device packages declare them in English
(devices/*/__init__.py, params.py, codec.py) and stay free of translation.

German takes the documents' own words; the comment before each group names its document and section (it goes
to the catalogs as the entries' note). A word that is a value of one live point carries that point as its
context: ``open`` of ``Gate state`` is the barrier's, ``open`` of ``Session`` the SCU's remote session's.
tests/test_i18n_catalog.py walks the tiles of every device type and fails on a text missing here.
"""

from __future__ import annotations

from app.i18n import N_, NP_

TILE_TEXTS = (
    # doc: HD-Lock, 000, section 3.1 (input registers 2, 8, 9) and 3.2.1 (LockStatus bits BoltLocked ... ProximityOverrange)
    N_("HD-Lock"), N_("door: unknown"), N_("bolt locked"), N_("bolt unlocked"), N_("bolt moving"), N_("bolt: unknown"),
    N_("hall sensors overdriven (magnet)"), N_("bolt {value} Inc"),
    # doc: CAN-M3IO, 001, sections 7.2.2 (TEMPx), 7.2.3 (Si, Triac, Last) and 7.2.4 (SSR outputs)
    N_("CAN-M3IO"), N_("outputs on: {list}"), N_("none"), N_("SSR{0} fuse blown"), N_("SSR{0} triac defective"),
    # doc: CAN-M3IO, 001, section 4.3 (HMR: Drehstromausgang; with P2 a Lastfehler unless exactly 2 of the 3 Lastausgänge
    # report a load): the module's check of the three-phase output SSR1-3 (devices/m3io/adapter.py P_LOAD_CHECK) and its states
    N_("SSR1-3 load check"), NP_("SSR1-3 load check", "ok"), NP_("SSR1-3 load check", "fault"),
    # doc: CAN-M3IO, 001, section 7.2.4.2.2 (Produktcode: Gerät): the products' names (devices/m3io/codec.py PRODUCT_CODES)
    NP_("Product", "MIO"), NP_("Product", "New KKD01"), NP_("Product", "KKD01"), NP_("Product", "KKD02"),
    NP_("Product", "ABB KKD01"), NP_("Product", "ABB KKD02"), NP_("Product", "HM01"), NP_("Product", "KM01 (until 07.11.2013)"),
    NP_("Product", "HMR01 (until 07.11.2013)"), NP_("Product", "KM01 (from 08.11.2013)"), NP_("Product", "HMR01 (from 08.11.2013)"),
    # doc: Electrak HD, 004, status telegram 0x07: Bewegungs-Flags and Fehler-Flags
    N_("Electrak HD network"), N_("moving: extending"), N_("moving: retracting"), N_("idle (no controller)"),
    N_("standing"), N_("waiting for status telegrams"), N_("actuators heard: {value}"), N_("actuators heard: {0}"),
    N_("actuators configured: {value}"), N_("{value:.1f} of {full:g} mm"),
    N_("Parameter"), N_("Current overload"), N_("Voltage"), N_("Temperature"), N_("Backdrive"), N_("Message timeout"),
    N_("Severe fault"), N_("Too few devices"),
    # doc: MO 64, 003, 5.1.3 tele_schrankenstatus (F_ereignis, LS, Baum ab) and 5.1.12 tele_torzustand
    N_("Bauer MO 64"), N_("gate: {text}"), N_("gate state: not read yet"), N_("position: {text}"),
    N_("fault event (F_ereignis)"), N_("Barrier status"), N_("light barrier interrupted"), N_("boom off (Baum ab)"), N_("{value} % open"),
    # doc: Ewellix SCU, 002, section 5 (remote session RO/RC/RA), data 0x0100 (Battery Mains), function F20
    N_("Ewellix SCU"), N_("remote session: {text}"), N_("remote session: closed"), N_("A1 {text}"),
    N_("A1: no position yet"), N_("supply: {text}"), N_("EMERGENCY STOP (F20) {text}"), N_("error: {text}"),
    N_("A1 {value} of {full} counts"),
)

POINT_WORDS = (
    # doc: HD-Lock, 000, section 3.1, input register 8 DoorState
    NP_("DoorState", "Undefined"), NP_("DoorState", "Door open"), NP_("DoorState", "Door closing"),
    NP_("DoorState", "Door closed"),
    # doc: HD-Lock, 000, section 3.1, input register 9 StateMachineState
    NP_("StateMachineState", "Start"), NP_("StateMachineState", "Referencing"), NP_("StateMachineState", "Unlocked"),
    NP_("StateMachineState", "Locking"), NP_("StateMachineState", "Locked"), NP_("StateMachineState", "Unlocking"),
    NP_("StateMachineState", "Error locked"), NP_("StateMachineState", "Error locking"),
    NP_("StateMachineState", "Error locking pause short"), NP_("StateMachineState", "Error locking pause long"),
    NP_("StateMachineState", "Error locking waiting"), NP_("StateMachineState", "Error unlocked"),
    NP_("StateMachineState", "Error unlocking"),
    # doc: HD-Lock, 000, section 3.1, input register 3 MotorState (Verfahr-Richtung) and 53 MotorState (Motorzustand)
    NP_("MotorState", "Inactive"), NP_("MotorState", "Extending"), NP_("MotorState", "Retracting"),
    NP_("MotorState", "Braking"), NP_("MotorState", "Forward"), NP_("MotorState", "Backward"),
    NP_("MotorState", "Braked"), NP_("MotorState", "Last state"), NP_("MotorState", "Active"),
    # doc: HD-Lock, 000, section 3.1, input register 54 MotorResult (Grund für letzten Motorstopp): the document's names
    NP_("MotorResult", "None"), NP_("MotorResult", "AtPos"), NP_("MotorResult", "MinSpeed"),
    NP_("MotorResult", "Timeout"), NP_("MotorResult", "userStop"), NP_("MotorResult", "OutStageDisabled"),
    NP_("MotorResult", "Currentlimit"),
    # doc: HD-Lock, 000, section 3.2.2 LockRequestSource (Bezeichnung; 0x80 and up: condition 2 always 1, the door ignored)
    NP_("LockRequestSource", "IrsNever"), NP_("LockRequestSource", "IrsAlways"), NP_("LockRequestSource", "IrsOverrange"),
    NP_("LockRequestSource", "IrsLine"), NP_("LockRequestSource", "IrsNotLine"),
    NP_("LockRequestSource", "IrsToggleOnLineEdge"), NP_("LockRequestSource", "IrsToggleOnLinePEdge"),
    NP_("LockRequestSource", "IrsToggleOnLineNEdge"), NP_("LockRequestSource", "IrsNever (door ignored)"),
    NP_("LockRequestSource", "IrsAlways (door ignored)"), NP_("LockRequestSource", "IrsOverrange (door ignored)"),
    NP_("LockRequestSource", "IrsLine (door ignored)"), NP_("LockRequestSource", "IrsNotLine (door ignored)"),
    NP_("LockRequestSource", "IrsToggleOnLineEdge (door ignored)"),
    NP_("LockRequestSource", "IrsToggleOnLinePEdge (door ignored)"),
    NP_("LockRequestSource", "IrsToggleOnLineNEdge (door ignored)"),
    # doc: MO 64, 003, 4 (LogiTed bus, TCP/IP) and 5.1.12 / page 33 (02 Auswahl index): the link, how often it polls, the
    # query form the unit takes (devices/mo64/adapter.py, facts.py)
    NP_("Connection", "connected"), NP_("Connection", "not connected"), NP_("Connection", "released"),
    NP_("Connection", "reconnecting"), NP_("Polling", "every cycle"),
    NP_("Polling", "gate state and position slower (changes are reported); status every cycle"),
    NP_("Query form", "not known yet"), NP_("Query form", "{0} Auswahl index (the document's, page {1})"),
    NP_("Query form", "{0} Auswahl (the document's form refused)"),
    # doc: MO 64, 003, 5.1.12 tele_torzustand 0x0C (Torzustand Bedeutung)
    NP_("Gate state", "opening"), NP_("Gate state", "closing"), NP_("Gate state", "pre-warning before opening"),
    NP_("Gate state", "pre-warning before closing"), NP_("Gate state", "open"), NP_("Gate state", "closed"),
    NP_("Gate state", "intermediate position"),
    # doc: Ewellix SCU, 002, section 5: the remote session (RO opens, RC keeps, RA ends it)
    NP_("Session", "closed"), NP_("Session", "opening"), NP_("Session", "open"), NP_("Session", "lost"),
    NP_("Session", "released"), N_("Session"),
    # doc: Ewellix SCU, 002, data ID 0x0100 Battery Mains: bit 0 mains, 1 battery, 2 charge controller, 3 charging
    NP_("Battery Mains", "mains connected"), NP_("Battery Mains", "battery connected"),
    NP_("Battery Mains", "charge controller on"), NP_("Battery Mains", "charging active"),
    # doc: Ewellix SCU, 002, data 0x0010 (Einheit: Encoder Flanken (Count)), 0x3011 (Wenn speed select relativ: Einheit: %;
    # absolut: Encoder Flanken/ s): the units of positions and speeds as devices/scu/model.py and params.py give them
    NP_("unit", "counts"), NP_("unit", "counts/mm"), NP_("unit", "% or counts/s"),
    # doc: CAN-M3IO, 001, section 7.2.2: readings outside 0-200 °C are out of the measuring range
    N_("out of range ({0})"),
    # doc: CAN-M3IO, 001, sections 6.1 (bit rate) and 4 (variants): the module against the plant file
    N_("bit rate mismatch: module {0} kbit/s, bus {1} kbit/s"),
    # doc: Ewellix SCU, 002, section 4.5, table 10 Fehlercodes (Error_Code 0x00D1): "bit n: cause", as devices/scu/codec.py
    # words them, joined by "; "
    NP_("Error code", "no error"), NP_("Error code", "bit {0}: CRC error in the ROM test (faulty ROM)"),
    NP_("Error code", "bit {0}: RAM test failed (faulty RAM)"), NP_("Error code", "bit {0}: CPU test failed (faulty CPU)"),
    NP_("Error code", "bit {0}: stack overflow detected"), NP_("Error code", "bit {0}: program flow error (watchdog reset)"),
    NP_("Error code", "bit {0}: hand switch test failed (short circuit in the hand switch)"),
    NP_("Error code", "bit {0}: binary input test failed (short circuit between binary inputs)"),
    NP_("Error code", "bit {0}: relay and FET test failed (faulty relay or FET)"),
    NP_("Error code", "bit {0}: communication with the MoveEnable controller failed"),
    NP_("Error code", "bit {0}: MoveEnable output check failed (the MoveEnable controller's output is wrong)"),
    NP_("Error code", "bit {0}: over-temperature at the rectifier or FET"),
    NP_("Error code", "bit {0}: switched off because of deep discharge of the battery"),
    NP_("Error code", "bit {0}: total current exceeded"), NP_("Error code", "bit {0}: error of actuator {1}"),
    NP_("Error code", "bit {0}: position difference between the actuators too large (synchronised parallel run)"),
    NP_("Error code", "bit {0}: remote communication timeout"),
    NP_("Error code", "bit {0}: locking box I{1}C communication error"),  # I2C: its digit is a number too
    NP_("Error code", "bit {0}: RAM copy of the EEPROM configuration data has a wrong CRC"),
    NP_("Error code", "bit {0}: RAM copy of the EEPROM user data has a wrong CRC"),
    NP_("Error code", "bit {0}: EEPROM locking box data has a wrong CRC"),
    NP_("Error code", "bit {0}: RAM copy of the EEPROM dynamic data has a wrong CRC"),
    NP_("Error code", "bit {0}: RAM copy of the EEPROM calibration data has a wrong CRC"),
    NP_("Error code", "bit {0}: RAM copy of the EEPROM calibration data has a wrong CRC (as printed for bit {1})"),
    NP_("Error code", "bit {0}: IO test"), NP_("Error code", "bit {0}: motions are not executed"),
    NP_("Error code", "bit {0}: not in table {1}"),
    # the MQTT broker's connection as the header and the plant-wide view show it (app/mqtt.py, app/site_view.py)
    NP_("broker", "starting"), NP_("broker", "connecting"), NP_("broker", "connected"), NP_("broker", "connected: client id taken over"),
    NP_("broker", "down"), NP_("broker", "stopped"),
)

# doc: MO 64, 003: what this tool assumes beyond the document's page summaries (devices/mo64/codec.py ASSUMPTIONS), shown
# on the barrier's page as such
MO64_ASSUMPTIONS = (
    N_("RS485 telegrams are assumed to be 55 LE DA SA type data CSH CSL, with LE counting DA to the end of the data and this tool's master address 0x00 by default (the manual's summary does not print the address fields)."),
    N_('The RS485 token telegram is assumed to be the shortest telegram of the manual (6 characters): 55 02 DA SA CSH CSL, sent by the master that holds the token to the next master DA.'),
    N_('TCP port 52719, the frame 55 LE type data CSH CSL and the reply types ack 0x01, nak 0x02, busy 0x03, syn 0x04 come from a public client, not from the manual.'),
    N_("Short commands (0x03) are sent as one command byte; the manual's summary names their effects (e.g. clearing a loop-adjust counter) but not their codes."),
    N_('The error memory level is chosen by an index byte after the query index; each answer carries index, error flags and time stamp.'),
    N_("Queries: the manual prints 02 Auswahl index (page 33), the public client sends 02 Auswahl; the manual's form is tried first and the unit's answer decides (shown as the query form)."),
    N_('Status bits: positions as the public client has them; the manual lists Multi3-6 before the loop adjustment bits and the MO 64 has six multi relays, so relays 7-14 are not shown.'),
    N_("Setting selectors 0x04 0x01 (pre-warning before opening) and 0x04 0x02 (pre-warning before closing) follow the order of the answer telegrams 0x0D-0x0F; the manual's summary names only 0x04 0x00 (open time) and 0x04 0x04 (change monitoring)."),
    N_("The vehicle counter (0x05 0x00) and the maintenance interval (0x05 0x01, u32) selectors are assumed; the manual's summary names the 32-bit vehicle counter setting but not its selector."),
    N_('The layouts of the counting function (0x11), loop periods (0x1B) and the fields of induction loops, direction logics, configuration flags and multi relays that the summary does not number are shown as raw values.'),
)
# doc: MO 64, 003, chapter 4 (Schreibzugriff auf das EEPROM): the declared risk of every setting write (devices/mo64/policy.py)
MO64_RISKS = (N_("Every setting write wears the barrier's EEPROM (chapter 4: the number of writes is limited). Write only what must change."),)
# doc: CAN-M3IO, 001, section 6.3 (Watchdog: 2 s, DigOut) and 7.2.1 (P2: a two-pole load at the three-phase output): the
# watchdog's and P2's words on the module's page (devices/m3io/adapter.py)
M3IO_WORDS = (
    N_("served: DigOut every {0} ms"), N_("served: DigOut every {0} ms (every output off: nobody controls the module)"),
    N_("served by another master (a PLC): this tool only listens"),
    N_("not served: outputs are off in the module; take control to serve it"),
    N_("read back once this tool serves the module"),
    N_("cannot be read back in simple mode (SW1 switch 8 off): sent with every DigOut"),
    N_("The product code has not been read yet: outputs stay off until it matches the plant file."),
)
# doc: CAN-M3IO, 001, section 7.2.4.2.2: the software version word, whose format the document does not give (devices/m3io/codec.py)
M3IO_ASSUMPTIONS = (N_("the document names the SW version word without its format; read as high byte . low byte (0x1201 = 18.1)"),)
# doc: Electrak HD, 004, status telegram 0x07: Bewegungs-Flags (names and meanings) and Fehler-Flags (meanings and how
# each clears), as devices/electrak/codec.py words them
ELECTRAK_FLAGS = (
    N_('Extending'),
    N_('moving out'),
    N_('Retracting'),
    N_('moving in'),
    N_('Saturated'),
    N_('moving at the highest speed the supply voltage and load allow; when driven over CAN make sure this does not stay set on any actuator, or the network cannot keep synchronised'),
    N_('Waiting'),
    N_('standing still, waiting for the other actuators to catch up'),
    N_('a value of the control telegram is outside the range allowed for the model; no motion while set'),
    N_("send values within the model's ranges"),
    N_('the last motion exceeded the calibrated current limit or the limit in the control telegram (longer than 40 ms, not during start-up); no motion while set'),
    N_('move in the opposite direction, or drop the enable bit'),
    N_('the supply voltage is outside the operating range; a running motion goes on for 10 s, no new motion'),
    N_('bring the supply voltage of every actuator back into range'),
    N_('the temperature is outside the operating range; a running motion goes on for 10 s, no new motion'),
    N_('let the actuators return to the operating temperature'),
    N_('the rod moved without a command (high static load or strong vibration)'),
    N_('check the load. Assumption (the document does not say how it clears): with the next commanded motion'),
    N_('no control telegram within the timeout (250 ms by default); no actuator moves while set'),
    N_('send control telegrams every 100 ms'),
    N_('no motion detected while driving the motor, or the position changed in the wrong direction; no motion while set'),
    N_('move in the opposite direction, or drop the enable bit'),
    N_('an actuator found fewer networked devices than expected; no motion while set'),
    N_('reconnect the missing actuator, or set the override/reset bit (or line) to reset the expected count'),
)
# doc: Electrak HD, 004: the declared risk of every motion of the network (devices/electrak/policy.py)
ELECTRAK_RISKS = (N_("The actuators move: check that the area is clear (nobody and nothing in the stroke of any actuator of the network, nor under the load they carry)."),)
# doc: Ewellix SCU, 002, table 7 (remote data: volatile) and the Safety_ID (what the unit does on a communication timeout),
# as devices/scu/model.py and codec.py word them
SCU_WORDS = (
    N_('volatile remote data (table 7): the unit keeps it until its next reset, then starts again with its configured default'),
    N_('On a communication timeout (0.5 s) every motion is stopped and none is started; after the timeout only RC, RA and RO are available.'),
    N_('On a communication timeout (0.5 s) every motion is stopped.'),
    N_('On a communication timeout (0.5 s) only the remote motion is stopped (firmware V2B3 and later).'),
)
# doc: Ewellix SCU, 002, sections 4.1 (RG outside remote mode) and 4.3 (the cyclic object 0x3001 with every RC): how the
# unit is watched, as devices/scu/adapter.py and opening.py word it
SCU_WATCH_WORDS = (
    N_("watching with RG outside a remote session: the unit answers RG without remote mode; the session (RO, RC) is opened only while someone holds control or a function runs"),
    N_("the remote session is open for reading only: the unit refuses RG outside remote mode (section 4.1); no RE is sent unless a page holds control"),
    N_("not known yet: the first RG outside a session tells"),
    N_("cyclic object 0x3001: positions, status 1 and 2, currents, error code, mains/battery with every RC"),
    N_("RC without data (the unit refused the cyclic object); live data is read with RG"),
)


# doc: the simulation card of every twin (devices/*/sim.py ``controls()``, shown by pages/simcontrols.py): titles,
# notes, actions and their parameters, a sentence each; values (numbers, hex literals, the plant's name) as {0}, {1} ...
SIM_WORDS = (
    NP_("simulation", "Simulated lock ({0})"),
    NP_("simulation", "Answer Set Modbus Address: section {0} does not say whether the lock answers the command write; off = it stays silent."),
    NP_("simulation", "Swap puts a factory-new unit with this serial number at the same address."),
    NP_("simulation", "Close door"),
    NP_("simulation", "Open door"),
    NP_("simulation", "Open / close door"),
    NP_("simulation", "LOCK-REQUEST input active"),
    NP_("simulation", "Strong magnet"),
    NP_("simulation", "Bolt blocked (never leaves its end position)"),
    NP_("simulation", "Locks with the door open (broken)"),
    NP_("simulation", "Stop answering"),
    NP_("simulation", "Answer Set Modbus Address at the old address"),
    NP_("simulation", "Refuse every write (exception {0})"),
    NP_("simulation", "Swap for a new device"),
    NP_("simulation", "New serial number"),
    NP_("simulation", "simulated lock runs at {0} bit/s, device ID {1} (ext {2})."),
    NP_("simulation", "Firmware-update mode"),
    NP_("simulation", "Back to the bus bit rate"),
    NP_("simulation", "simulated lock runs at {0} bit/s, device ID {1} (std {2})."),
    NP_("simulation", "Simulated actuators ({0})"),
    NP_("simulation", "Load raises the motor current (above the limit: overload); a rod load moves a standing rod (Backdrive; negative pushes it in); an active manual control line makes the network send {0} itself; the disagreeing actuator's soft start time differs, so reads of it fail."),
    NP_("simulation", "Set load"),
    NP_("simulation", "extra load [A]"),
    NP_("simulation", "Set static load"),
    NP_("simulation", "rod load [mm/s]"),
    NP_("simulation", "actuator {0} connected"),
    NP_("simulation", "Supply voltage fault"),
    NP_("simulation", "Temperature fault"),
    NP_("simulation", "Set manual control line"),
    NP_("simulation", "{0} out, {1} in, {2} off"),
    NP_("simulation", "last actuator disagrees"),
    NP_("simulation", "Power-cycle actuators"),
    NP_("simulation", "Simulated module ({0})"),
    NP_("simulation", "Toggle the inputs E{0}-E{1}; an SSR's faults by its number."),
    NP_("simulation", "The module reports a blown fuse until its {0} V are cut, even after repair."),
    NP_("simulation", "E{0}"),
    NP_("simulation", "Remove load"),
    NP_("simulation", "SSR"),
    NP_("simulation", "Connect load"),
    NP_("simulation", "Blow fuse"),
    NP_("simulation", "Break triac"),
    NP_("simulation", "Short triac"),
    NP_("simulation", "Repair"),
    NP_("simulation", "Set"),
    NP_("simulation", "Pt{0} input"),
    NP_("simulation", "{0} °C"),
    NP_("simulation", "Cut {0} V (reset)"),
    NP_("simulation", "Simulated SCU ({0})"),
    NP_("simulation", "Load raises the current of a moving actuator (above {0} A it trips); an actuator error stops it fast and sets its error bit; a dropped line ends remote mode within {1} ms; a reset ends remote mode and sets the remote speeds and positions back to their defaults (volatile, table {2})."),
    NP_("simulation", "Add load"),
    NP_("simulation", "load on actuator"),
    NP_("simulation", "load [A]"),
    NP_("simulation", "Trip actuator error"),
    NP_("simulation", "actuator"),
    NP_("simulation", "On battery (mains off)"),
    NP_("simulation", "Line dropped (no answers)"),
    # the SCU twin's switch names as its audit rows say them (devices/scu/sim.py declares them; "on battery on")
    NP_("simulation", "on battery"),
    NP_("simulation", "line dropped"),
    NP_("simulation", "Reset the unit"),
    NP_("simulation", "Simulated barrier ({0})"),
    NP_("simulation", "A vehicle opens the barrier on loop A and passes the light barrier; a fault stops the motor and is recorded in the error memory; after mains the position is unknown until an end position."),
    NP_("simulation", "Drive a vehicle through"),
    NP_("simulation", "Light barrier interrupted"),
    NP_("simulation", "Light barrier: interrupt at the next close / free"),
    NP_("simulation", "Loop A occupied"),
    NP_("simulation", "Loop B occupied"),
    NP_("simulation", "Loop C occupied"),
    NP_("simulation", "Loop A: occupy / free"),
    NP_("simulation", "Loop B: occupy / free"),
    NP_("simulation", "Loop C: occupy / free"),
    NP_("simulation", "Light barrier never reports (broken)"),
    NP_("simulation", "Raise fault"),
    NP_("simulation", "error flags"),
    NP_("simulation", "Clear faults"),
    NP_("simulation", "Mains back (power up)"),
)

# doc: HD-Lock, 000, sections 3.1 (input registers 0, 1, 11), 3.2.4 (Ausgang 1/2: Registerwert), 3.2.6 and holding 101
# (Parity): the values of the registers the parameter model names in English, as the register tables and entries show them
HDLOCK_VALUES = (
    NP_("LockState", "Unlocked (bolt retracted)"), NP_("LockState", "Locked (bolt extended)"),
    NP_("LockRequest", "Inactive"), NP_("LockRequest", "Active"),
    NP_("Direction", "Always right-hinged"), NP_("Direction", "Automatic"), NP_("Direction", "Always left-hinged"),
    NP_("SettingsDirection", "Always right-hinged"), NP_("SettingsDirection", "Automatic"), NP_("SettingsDirection", "Always left-hinged"),
    NP_("SettingsOutput1", "Always off"), NP_("SettingsOutput1", "Always on"), NP_("SettingsOutput1", "Door closed"), NP_("SettingsOutput1", "Door open"), NP_("SettingsOutput1", "Bolt extended"), NP_("SettingsOutput1", "Bolt retracted"), NP_("SettingsOutput1", "Lock request"), NP_("SettingsOutput1", "No lock request"), NP_("SettingsOutput1", "Blink ~1 Hz"), NP_("SettingsOutput1", "Hall sensors overdriven"),
    NP_("SettingsOutput2", "Always off"), NP_("SettingsOutput2", "Always on"), NP_("SettingsOutput2", "Door closed"), NP_("SettingsOutput2", "Door open"), NP_("SettingsOutput2", "Bolt extended"), NP_("SettingsOutput2", "Bolt retracted"), NP_("SettingsOutput2", "Lock request"), NP_("SettingsOutput2", "No lock request"), NP_("SettingsOutput2", "Blink ~1 Hz"), NP_("SettingsOutput2", "Hall sensors overdriven"),
    NP_("SettingOutput1", "Always off"), NP_("SettingOutput1", "Always on"), NP_("SettingOutput1", "Door closed"), NP_("SettingOutput1", "Door open"), NP_("SettingOutput1", "Bolt extended"), NP_("SettingOutput1", "Bolt retracted"), NP_("SettingOutput1", "Lock request"), NP_("SettingOutput1", "No lock request"), NP_("SettingOutput1", "Blink ~1 Hz"), NP_("SettingOutput1", "Hall sensors overdriven"),
    NP_("SettingOutput2", "Always off"), NP_("SettingOutput2", "Always on"), NP_("SettingOutput2", "Door closed"), NP_("SettingOutput2", "Door open"), NP_("SettingOutput2", "Bolt extended"), NP_("SettingOutput2", "Bolt retracted"), NP_("SettingOutput2", "Lock request"), NP_("SettingOutput2", "No lock request"), NP_("SettingOutput2", "Blink ~1 Hz"), NP_("SettingOutput2", "Hall sensors overdriven"),
    NP_("Parity", "None"), NP_("Parity", "Odd"), NP_("Parity", "Even"),
    NP_("SettingsRemoveMagnet", "Off (secure)"), NP_("SettingsRemoveMagnet", "Retract when magnet removed"),
    # doc: CAN-M3IO, 001, section 4.3 and 7.2.4 (P2: Drehstromausgang mit zweiphasiger Last)
    NP_("P2", "three-phase load"), NP_("P2", "two-phase load (P2)"),
    # doc: MO 64, 003, chapter 5.1.25 (Multirelais: Störung)
    NP_("multi1", "fault"), NP_("multi2", "fault"), NP_("multi3", "fault"), NP_("multi4", "fault"), NP_("multi5", "fault"), NP_("multi6", "fault"),
    # doc: Ewellix SCU, 002, table 9 (RE para_ID[1] motion_stop: 0 ohne, 1 mit Start/Stop-Rampe, -1 wie konfiguriert)
    NP_("Ramp", "fast"), NP_("Ramp", "soft"), NP_("Ramp", "default"),
    # doc: Ewellix SCU, 002, table 3 (RO, Safety_ID 0, 1, 2)
    NP_("Safety_ID", "no start after timeout"), NP_("Safety_ID", "stop all"), NP_("Safety_ID", "stop remote"),
)
