// Names of horses and riders by id, for tables that only carry the ids.

import { get, itemsOf } from "./api.js";

export async function nameLookups() {
  const [horses, riders] = await Promise.all([
    get("/api/horses", { params: { limit: 500 } }),
    get("/api/riders", { params: { limit: 500 } }),
  ]);
  const byId = (items) => new Map(itemsOf(items).map((item) => [item.id, item]));
  return { horses: byId(horses), riders: byId(riders) };
}

export function horseName(ride, lookups) {
  return ride.horse?.name ?? ride.horse_name ?? lookups?.horses.get(ride.horse_id)?.name ?? `horse ${ride.horse_id}`;
}

export function riderName(ride, lookups) {
  return ride.rider?.name ?? ride.rider_name ?? lookups?.riders.get(ride.rider_id)?.name ?? `rider ${ride.rider_id}`;
}
