"""The settings of a CAN-M3IO through its parameter model (:mod:`devices.m3io.params`): customer-data
records, P2, the area 2 identity and SW1; read, written with read-back, backed up and restored.

A part of :class:`devices.m3io.adapter.M3ioAdapter` (it inherits :class:`ModuleSettings`), kept here so
the adapter keeps the conversation and the safety rules. The values go into the live store's registers
(``state.raw(param)``), where drift, projects and the replacement assistant read them.
"""

from __future__ import annotations

import time

from devices.adapter import BackupDefaults
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.m3io.params import (ADDRESSING, CFG, CONFIG, CONFIG_PARAMS, CUSTOMER, P2_OPTION, P2_PARAM, PARAMS, RECORD_PARAMS,
                                 SW1_PARAM, record_bytes, record_param, record_raw)
from devices.message import Message, N_, message_of
from devices.params import Accepted, Param, ParamError, backup_entry

# 7.2.4.2.4: the module answers a written record only once it is stored, and is deaf meanwhile; the document
# gives no time for it, so the answer is awaited far longer than an ordinary request's (control.MDATA_TIMEOUT_S)
STORE_TIMEOUT_S = 3.0
SETTINGS_RETRY_S = 5.0  # the settings could not be read when the module first answered: again after this long


class ModuleSettings(BackupDefaults):
    """Settings of the module (a part of the adapter: it uses its ``state``, ``ids``, ``variant``, ``_request``)."""

    def _init_settings(self) -> None:
        self.state.params = PARAMS
        self.state.registers_periodic = False  # read on demand: the module's records do not age
        self._settings_read = False  # addressed mode: every setting read once since the module (re)appeared
        self._settings_after = 0.0
        self._keep(SW1_PARAM, self.sw1)
        if self.variant is Variant.HMR:
            self._keep(P2_PARAM, int(self.two_phase))

    def _keep(self, param: Param, raw: int, answered: bool = False) -> None:
        """``raw`` of ``param`` into the live store (its words in the param's slots); ``answered``: the module said so."""
        now = time.time()
        for slot, word in zip(param.addresses, param.split(raw)):
            if answered:
                self.state.update_registers(param.space, slot, [word], now)
            else:
                self.state.registers[(param.space, slot)] = (word, now)
        self.state.touch()

    def plant_options(self) -> dict:
        """The device options the plant file should hold so that a restart starts as now: P2 of an HMR."""
        return {P2_OPTION: bool(self.two_phase)} if self.variant is Variant.HMR else {}

    # -- customer data (7.2.4.2.3/4) ----------------------------------------------------------------
    async def read_customer(self, index: int) -> bytes:
        param = self._record(index)
        answer = await self._request(codec.AREA_READ_CUSTOMER, index)
        self._publish_customer(index, answer.payload)
        self._keep(param, record_raw(answer.payload), answered=True)
        return answer.payload

    async def write_customer(self, index: int, payload: bytes) -> bytes:
        """Write and verify: the answer is what the module stored (7.2.4.2.4)."""
        param = self._record(index)
        if len(payload) > 6:
            raise self.error_type(f"a customer record holds 6 bytes, got {len(payload)}")
        answer = await self._request(codec.AREA_WRITE_CUSTOMER, index, payload, timeout=STORE_TIMEOUT_S)
        self._publish_customer(index, answer.payload)
        self._keep(param, record_raw(answer.payload), answered=True)
        if answer.payload != codec.pad6(payload):
            self.state.counters.write_errors += 1
            raise self.error_type(
                f"customer record {index}: the module stored {answer.payload.hex(' ')} instead of "
                f"{codec.pad6(payload).hex(' ')}: write it again"
            )
        self.state.event("info", Message(N_("customer record {index} = {data} written and verified"), index=index,
                                         data=answer.payload.hex(" ")))
        return answer.payload

    def _record(self, index: int) -> Param:
        try:
            return record_param(index)
        except ParamError as exc:
            raise self.error_type(str(exc)) from None

    def _publish_customer(self, index: int, payload: bytes) -> None:
        self.state.publish(f"Customer data {index}", payload.hex(" "), raw=list(payload), periodic=False)

    # -- P2 (4.3, 7.2.4) -------------------------------------------------------------------------------
    def _p2_changed(self, on: bool) -> None:
        self.two_phase = bool(on)
        self._keep(P2_PARAM, int(self.two_phase))

    async def _write_p2(self, on: bool) -> int:
        """Set P2 (what this tool sends with every DigOut period); in addressed mode also write it in area 1
        index 15 and compare the module's answer (7.2.4.2.1)."""
        self.set_two_phase(on)
        if not self.ids.addressed:
            return int(on)
        cfg = codec.encode_sync_cfg(on)
        try:
            answer = await self._request(codec.AREA_WRITE_CONFIG, codec.CONFIG_DYNAMIC, cfg)
        except self.error_type as exc:
            raise self.error_type(f"P2 {int(on)} is sent with every DigOut period, but area 1 index 15 was not "
                                  f"answered ({exc}): a firmware before 17.0 has no P2 (section 4.3)") from None
        self._keep(PARAMS.get(CONFIG, codec.CONFIG_DYNAMIC), answer.payload[0], answered=True)
        self._check_p2(answer.payload[0])
        if bool(answer.payload[0] & codec.P2) != bool(on):
            self.state.counters.write_errors += 1
            raise self.error_type(f"P2: the module answers cfg 0x{answer.payload[0]:02X} to P2 {int(on)} (area 1 index 15)")
        return int(on)

    # -- the parameter model's read and write (app/backup.py, projects, batch, the page) ------------------
    async def read_param(self, param: Param) -> int:
        """The value of ``param`` from the module (records and area 2, addressed mode), or as this tool holds it
        (SW1; P2, checked against area 2 index 15 in addressed mode)."""
        if param.space == ADDRESSING:
            return self.sw1
        if param.space == CFG:
            if self.variant is not Variant.HMR:
                raise self.error_type("P2 (two-phase load) exists on the HMR only")
            if self.ids.addressed:
                await self.read_param(PARAMS.get(CONFIG, codec.CONFIG_DYNAMIC))
            return int(self.two_phase)
        if param.space == CUSTOMER:
            return record_raw(await self.read_customer(param.address))
        if param.space == CONFIG:
            answer = await self._request(codec.AREA_READ_CONFIG, param.address)
            raw = int.from_bytes(answer.payload[:param.size], "little")
            self._keep(param, raw, answered=True)
            if param.address == codec.CONFIG_DYNAMIC:
                self._check_p2(raw)
            elif param.address == codec.CONFIG_PRODUCT:
                self._set_product(raw)
            return raw
        raise self.error_type(f"{param.name} is not a parameter of a CAN-M3IO")

    async def write_param(self, param: Param, value, *, confirmed: bool = False) -> int:
        """An entry for ``param``, checked by the model (range, bytes, P2's confirmation), written by
        :meth:`write_accepted`."""
        try:
            accepted = param.accept(value)
        except ParamError as exc:
            raise self.error_type(str(exc)) from None
        return await self.write_accepted(accepted, confirmed=confirmed)

    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        """What the model accepted, written and read back: a record from the module's answer (7.2.4.2.4), P2 from
        area 1's answer in addressed mode."""
        param = accepted.param
        try:
            raw = accepted.cleared(confirmed)
        except ParamError as exc:
            raise self.error_type(str(exc)) from None
        if param.space == CUSTOMER:
            await self.write_customer(param.address, record_bytes(raw))
        elif param.space == CFG:
            if self.variant is not Variant.HMR:
                raise self.error_type("P2 (two-phase load) exists on the HMR only")
            await self._write_p2(bool(raw))
        else:
            raise self.error_type(f"{param.name} is not writable")
        return raw

    def _keep_identity(self, serial: int, product: int, version: int, config: int) -> None:
        """The area 2 values read by ``read_identity`` into the live store (7.2.4.2.2)."""
        for param, raw in zip(CONFIG_PARAMS, (serial, product, version, config)):
            self._keep(param, raw, answered=True)

    async def read_settings(self) -> None:
        """The area 2 values and every customer record once (addressed mode), so drift and projects see the module."""
        await self.read_identity()
        for param in RECORD_PARAMS:
            await self.read_param(param)
        self._settings_read = True

    async def _read_settings_once(self) -> None:
        """poll(): read the settings when the module first answers in addressed mode, and again after a silence."""
        if self._settings_read or time.time() < self._settings_after:
            return
        try:
            await self.read_settings()
        except self.error_type as exc:
            self._settings_after = time.time() + SETTINGS_RETRY_S
            self.state.error(Message(N_("settings not read: {error}"), error=message_of(exc)), log=False)

    # -- backup and restore (app/backup.py) ------------------------------------------------------
    @property
    def backup_available(self) -> bool:
        """Addressed mode has stored data (customer records); an HMR has P2, which this tool keeps."""
        return self.ids.addressed or self.variant is Variant.HMR

    async def backup_read(self, progress=None) -> list[dict]:
        """SW1, P2 (HMR), and in addressed mode the area 2 values (for reference) and the 15 customer records."""
        if not self.backup_available:
            raise self.error_type(Message(N_("nothing to back up: customer data needs addressed mode (SW1 switch 8 on; "
                                             "SW1 is 0x{sw1:02X}) and P2 exists on the HMR only"), sw1=self.sw1))
        if self.ids.addressed:
            await self.read_identity()  # the area 2 values, for reference (and the page's identity record)
        entries = [backup_entry(SW1_PARAM, self.sw1)]
        if self.variant is Variant.HMR:
            entries.append(backup_entry(P2_PARAM, await self.read_param(P2_PARAM)))
        if self.ids.addressed:
            entries += [backup_entry(p, self.state.raw(p)) for p in CONFIG_PARAMS]
            for param in RECORD_PARAMS:
                entries.append(backup_entry(param, await self.read_param(param)))
                if progress:
                    progress(param.address / len(RECORD_PARAMS))
            self._settings_read = True
        return entries

    def backup_identity(self) -> dict:
        identity = self.identity
        return {"serial": identity and identity.serial, "product": identity and identity.product,
                "version": identity and identity.version, "variant": self.variant.value, "sw1": self.sw1}

    async def restore_entry(self, key: str, raw, *, confirmed: bool = False) -> str:
        """An entry of a backup by key through the model's write; returns what the module holds now."""
        param = PARAMS.by_key.get(key)
        if param is None or not param.writable:
            raise self.error_type(f"{key} is not writable")
        stored = await self.write_param(param, raw, confirmed=confirmed)
        return param.display(stored)

    async def save_step(self) -> None:
        return None  # every customer record is stored when written; P2 is kept in the plant file
