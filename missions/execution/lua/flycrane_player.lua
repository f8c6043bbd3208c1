--[[
FlyCrane onboard trajectory player, for stock ArduCopter (>= 4.5) with Lua scripting.

During a mission item NAV_SCRIPT_TIME (42702) whose command (param1) is 1, in AUTO, it
plays the drone's trajectory file, uploaded by MAVLink FTP as "flycrane_trajectory.bin",
with position + velocity + acceleration targets (vehicle:set_target_posvelaccel_NED),
against the group time the ground station sends. Through a lost link it keeps playing the
last group-time segment it received; at the end of the trajectory it holds the last point
and ends the item (vehicle:nav_script_time_done), so the mission goes on to its next item.

Group time arrives as DEBUG_FLOAT_ARRAY (350) named "GT": time_usec = t0, this vehicle's
millis() at which plan time is data[0] (tau0, s); the rate is data[1] at t0 and goes
linearly to data[2] over data[3] seconds, then stays; data[4] is the segment's sequence
number; data[5] and data[6] how far ahead of now [s] the targets are, horizontally and
vertically (what the position controller lags them by). A segment governs from its t0
until a later one's: one that arrives before its t0 (this vehicle's clock behind the
ground's) waits. Before the first, the player holds the trajectory's first point.
The trajectory is placed horizontally from the planned home in the file's header, as the
ground's targets are, and vertically from the vehicle's home.

File (little endian): "FCT1", uint32 n, float32 dt, int32 home lat, int32 home lon
[1e-7 deg], float32 home alt AMSL [m] (24 bytes), then n rows of 10 float32: t, north,
east, down [m] from home (north and east in this vehicle's metres, as its Location measures
them from that home), velocity [m/s], acceleration [m/s^2] (NED). Rows are read in
windows, so memory does not grow with the file. Lua numbers here are 32-bit integers and
single-precision floats: times stay in milliseconds since boot and seconds of plan time.
--]]

local FILE = "flycrane_trajectory.bin"
local PLAYER_COMMAND = 1
local DEBUG_FLOAT_ARRAY = 350
local MODE_AUTO = 3
local PERIOD_MS = 20
local HEADER_BYTES, ROW_BYTES, WINDOW_ROWS = 24, 40, 64
local INFO, WARNING = 6, 4

-- the receive queue's depth first, then the number of message ids (ArduPilot 4.5's order)
mavlink:init(8, 1)
mavlink:register_rx_msgid(DEBUG_FLOAT_ARRAY)

local trajectory = nil  -- {file, n, dt, duration, first, count, window, lat, lon}
local segment = nil     -- the governing one: {t0, tau0, rate, rate_end, ramp, seq,
                        -- lead_h, lead_v}
local waiting = {}      -- later ones whose t0 is still ahead, by sequence
local MAX_WAITING = 8
local active = nil      -- the NAV_SCRIPT_TIME item being played
local home_offset = nil -- home in the EKF origin's NED frame
local yaw = 0
local finished = false

local function say(severity, text)
  gcs:send_text(severity, "FlyCrane player: " .. text)
end

local function open_trajectory()
  local file = io.open(FILE, "rb")
  if not file then
    return nil, "no " .. FILE
  end
  local size = file:seek("end")
  file:seek("set", 0)
  local header = file:read(HEADER_BYTES)
  if not header or #header < HEADER_BYTES then
    file:close()
    return nil, "short header"
  end
  local magic, n, dt, lat, lon = string.unpack("<c4I4fi4i4", header)
  if magic ~= "FCT1" or n < 2 or dt <= 0 or size < HEADER_BYTES + n * ROW_BYTES then
    file:close()
    return nil, "not a trajectory of this version"
  end
  return {file = file, n = n, dt = dt, duration = (n - 1) * dt, first = -1, count = 0,
          lat = lat, lon = lon}
end

local function row(k)
  local t = trajectory
  if k < t.first or k >= t.first + t.count then
    t.first = math.max(0, k - 1)
    t.file:seek("set", HEADER_BYTES + t.first * ROW_BYTES)
    t.window = t.file:read(WINDOW_ROWS * ROW_BYTES)
    t.count = t.window and (#t.window // ROW_BYTES) or 0
  end
  return string.unpack("<ffffffffff", t.window, 1 + (k - t.first) * ROW_BYTES)
end

-- position and velocity by cubic Hermite interpolation, acceleration linear
local function sample(tau)
  local t = trajectory
  local u = math.max(0, math.min(tau / t.dt, t.n - 1))
  local k = math.min(math.floor(u), t.n - 2)
  local s = u - k
  local h = t.dt
  local _, pn0, pe0, pd0, vn0, ve0, vd0, an0, ae0, ad0 = row(k)
  local _, pn1, pe1, pd1, vn1, ve1, vd1, an1, ae1, ad1 = row(k + 1)
  local s2, s3 = s * s, s * s * s
  local h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
  local d00, d10, d01, d11 = (6 * s2 - 6 * s) / h, 3 * s2 - 4 * s + 1, (6 * s - 6 * s2) / h, 3 * s2 - 2 * s
  local function p(a, va, b, vb) return h00 * a + h10 * h * va + h01 * b + h11 * h * vb end
  local function v(a, va, b, vb) return d00 * a + d10 * va + d01 * b + d11 * vb end
  local function a(x, y) return (1 - s) * x + s * y end
  return p(pn0, vn0, pn1, vn1), p(pe0, ve0, pe1, ve1), p(pd0, vd0, pd1, vd1),
         v(pn0, vn0, pn1, vn1), v(pe0, ve0, pe1, ve1), v(pd0, vd0, pd1, vd1),
         a(an0, an1), a(ae0, ae1), a(ad0, ad1)
end

local function receive()
  for _ = 1, 8 do
    local msg = mavlink:receive_chan()
    if not msg then
      return
    end
    -- ArduPilot 4.5 hands over its 291-byte mavlink_message_t (payload at byte 13);
    -- later versions a 299-byte one (payload at 16)
    local id_at, payload = 10, 13
    if #msg >= 299 then
      id_at, payload = 13, 16
    end
    if string.unpack("<I3", msg, id_at) == DEBUG_FLOAT_ARRAY then
      -- DEBUG_FLOAT_ARRAY wire order: time_usec u64, array_id u16, name c10, data f32[58]
      local t0, _, _, name, tau0, rate, rate_end, ramp, seq, lead_h, lead_v =
        string.unpack("<I4I4I2c10fffffff", msg, payload)
      name = name:gsub("%z", "")
      local last = waiting[#waiting] or segment
      if name == "GT" and (last == nil or seq > last.seq) and #waiting < MAX_WAITING then
        waiting[#waiting + 1] = {t0 = t0, tau0 = tau0, rate = rate, rate_end = rate_end,
                                 ramp = ramp, seq = seq, lead_h = lead_h, lead_v = lead_v}
      end
    end
  end
end

-- the segment that governs at this vehicle's millis() now
local function advance(now)
  while waiting[1] and (segment == nil or now >= waiting[1].t0) do
    segment = table.remove(waiting, 1)
  end
end

-- plan time, rate and the rate's change at ``ahead`` seconds past millis() now
local function group_time(now, ahead)
  if not segment then
    return 0, 0, 0
  end
  local dt = math.max(0, (now - segment.t0) * 0.001 + ahead)
  local s = segment
  if s.ramp > 0 and dt < s.ramp then
    local slope = (s.rate_end - s.rate) / s.ramp
    return s.tau0 + s.rate * dt + 0.5 * slope * dt * dt, s.rate + slope * dt, slope
  end
  local ramped = s.tau0 + 0.5 * (s.rate + s.rate_end) * s.ramp
  return ramped + s.rate_end * (dt - s.ramp), s.rate_end, 0
end

local target, velocity, acceleration = Vector3f(), Vector3f(), Vector3f()

-- the trajectory ``ahead`` seconds past now: position, velocity and acceleration (NED)
local function led(now, ahead)
  local tau, rate, slope = group_time(now, ahead)
  if tau >= trajectory.duration then
    tau, rate, slope = trajectory.duration, 0, 0
  end
  local pn, pe, pd, vn, ve, vd, an, ae, ad = sample(tau)
  -- the file holds d/dtau; the vehicle needs d/dt
  local r2 = rate * rate
  return pn, pe, pd, vn * rate, ve * rate, vd * rate,
         an * r2 + vn * slope, ae * r2 + ve * slope, ad * r2 + vd * slope
end

local function play(now)
  advance(now)
  local lead_h, lead_v = 0, 0
  if segment then
    lead_h, lead_v = segment.lead_h, segment.lead_v
  end
  local pn, pe, _, vn, ve, _, an, ae, _ = led(now, lead_h)
  local _, _, pd, _, _, vd, _, _, ad = led(now, lead_v)
  target:x(pn + home_offset[1]); target:y(pe + home_offset[2]); target:z(pd + home_offset[3])
  velocity:x(vn); velocity:y(ve); velocity:z(vd)
  acceleration:x(an); acceleration:y(ae); acceleration:z(ad)
  vehicle:set_target_posvelaccel_NED(target, velocity, acceleration, true, yaw, false, 0, false)
  local tau = group_time(now, 0)
  if tau >= trajectory.duration and not finished then
    finished = true
    say(INFO, "trajectory played")
    vehicle:nav_script_time_done(active)
  end
end

local function begin(id)
  active, finished = id, false
  if trajectory then
    trajectory.file:close()
  end
  local err
  trajectory, err = open_trajectory()
  local origin = ahrs:get_relative_position_NED_origin()
  local home = ahrs:get_relative_position_NED_home()
  local ekf_origin = ahrs:get_origin()
  if not trajectory or not origin or not home or not ekf_origin then
    say(WARNING, "cannot play: " .. (err or "no position"))
    vehicle:nav_script_time_done(id)
    active = nil
    return
  end
  -- horizontally from the planned home (the file's), as the ground's targets: the home
  -- set at arming lies where the estimate was then, centimetres off; vertically from
  -- that home, whose height the mission's altitudes count from
  local planned = Location()
  planned:lat(trajectory.lat)
  planned:lng(trajectory.lon)
  local north_east = ekf_origin:get_distance_NE(planned)
  home_offset = {north_east:x(), north_east:y(), origin:z() - home:z()}
  yaw = math.deg(ahrs:get_yaw())
  say(INFO, string.format("playing %d rows", trajectory.n))
end

local function step()
  receive()
  local id, command = nil, nil
  if vehicle:get_mode() == MODE_AUTO then
    id, command = vehicle:nav_script_time()
  end
  if id and command == PLAYER_COMMAND then
    if id ~= active then
      begin(id)
    end
    if active == id then
      play(millis():toint())
    end
  elseif active then
    active = nil
  end
end

-- an error must not end the script: a dead player leaves the vehicle on its last velocity
-- and acceleration until GUID_TIMEOUT
function update()
  local ok, err = pcall(step)
  if not ok then
    say(WARNING, tostring(err))
  end
  return update, PERIOD_MS
end

say(INFO, "ready")
return update, 1000
